"""Output folders: whole or absent, one writer at a time, stale temporaries cleaned, the umask
honoured. Kill tests of the real CLI are in tests/baselines/test_cli_scenario_kill.py.
"""

import os
import stat
from pathlib import Path

import pytest

from scenario_gen import InputError, atomic
from scenario_gen.atomic import clean_stale, output_dir


def _write(d: Path, text: str) -> None:
    (d / "data.txt").write_text(text)
    (d / "sub").mkdir()
    (d / "sub" / "more.txt").write_text(text)


def test_second_writer_of_the_same_out_is_refused(tmp_path: Path) -> None:
    out = tmp_path / "out"
    with output_dir(out) as tmp:
        _write(tmp, "first")
        with pytest.raises(InputError) as info, output_dir(out):
            pass
        assert info.value.field == "out" and "another run" in str(info.value)
        with output_dir(tmp_path / "other") as other:  # another folder is not blocked
            _write(other, "x")
    assert (out / "data.txt").read_text() == "first"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["other", "out"]  # lock files gone


def test_lock_file_replaced_under_a_waiting_run_is_not_shared(tmp_path: Path, monkeypatch) -> None:
    # A run that opened the lock file just before its holder removed it gets the lock on that
    # removed file; it must notice and lock the file the path names now, or a third run could
    # lock that one and both would write.
    out = tmp_path / "out"
    lock = tmp_path / ".out.lock"
    lock.write_text("")
    stale_fd = os.open(lock, os.O_RDWR)
    lock.unlink()  # the holder finished and removed it
    real_open = os.open
    calls = []

    def late_open(path: object, flags: int, mode: int = 0o777) -> int:
        calls.append(path)
        return stale_fd if len(calls) == 1 else real_open(path, flags, mode)  # type: ignore[arg-type]

    monkeypatch.setattr(atomic.os, "open", late_open)
    with output_dir(out) as tmp:
        monkeypatch.setattr(atomic.os, "open", real_open)
        _write(tmp, "a")
        assert lock.exists()  # it retried and holds the lock the path names
        with pytest.raises(InputError, match="another run"), output_dir(out, True):
            pass
    assert len(calls) == 2


def test_stale_temporaries_are_removed_and_others_kept(tmp_path: Path) -> None:
    out = tmp_path / "scn"
    stale = [
        tmp_path / ".scn.tmp-4000000-abcd_123",  # a run killed mid-write (pid beyond pid_max)
        tmp_path / f".scn.tmp-{os.getpid()}-zzzzzzzz",  # even one with a live pid: lock held
    ]
    keep = [
        tmp_path / ".scn2.tmp-4000000-abcdefgh",  # another folder's temporary
        tmp_path / ".scn.tmp-5.tmp-4000000-abcdefgh",  # the temporary of a folder "scn.tmp-5"
        tmp_path / "scn.tmp-notes",
    ]
    for p in stale + keep:
        p.mkdir()
        (p / "partial.csv").write_text("1,2")
    with output_dir(out) as tmp:
        _write(tmp, "new")
    assert all(not p.exists() for p in stale)
    assert all(p.exists() for p in keep)


def test_old_copy_orphaned_between_two_renames_is_restored(tmp_path: Path) -> None:
    # without renameat2 a replace renames the old folder aside, then the new one in; a kill
    # between the two leaves only .scn.old-<pid>: the next run puts it back first
    out = tmp_path / "scn"
    old = tmp_path / ".scn.old-4000000"
    old.mkdir()
    _write(old, "old")
    with pytest.raises(InputError, match="already exists"), output_dir(out):
        pass
    assert (out / "data.txt").read_text() == "old" and not old.exists()


def test_replace_without_renameat2_leaves_no_old_copy(tmp_path: Path, monkeypatch) -> None:
    out = tmp_path / "scn"
    with output_dir(out) as tmp:
        _write(tmp, "old")
    monkeypatch.setattr(atomic, "_exchange", lambda a, b: False)
    with output_dir(out, overwrite=True) as tmp:
        _write(tmp, "new")
    assert (out / "data.txt").read_text() == "new"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["scn"]


def test_replace_swaps_in_one_step(tmp_path: Path) -> None:
    out = tmp_path / "scn"
    with output_dir(out) as tmp:
        _write(tmp, "old")
    inode = out.stat().st_ino
    with output_dir(out, overwrite=True) as tmp:
        _write(tmp, "new")
        assert (out / "data.txt").read_text() == "old"  # untouched until the swap
    assert (out / "data.txt").read_text() == "new" and out.stat().st_ino != inode
    assert sorted(p.name for p in tmp_path.iterdir()) == ["scn"]


def test_failure_leaves_nothing_not_even_the_parents_it_made(tmp_path: Path) -> None:
    out = tmp_path / "a" / "b" / "scn"
    with pytest.raises(RuntimeError), output_dir(out) as tmp:
        _write(tmp, "x")
        raise RuntimeError("disk full")
    assert list(tmp_path.iterdir()) == []
    (tmp_path / "a").mkdir()  # a parent that existed before stays
    with pytest.raises(RuntimeError), output_dir(out):
        raise RuntimeError("again")
    assert [p.name for p in tmp_path.iterdir()] == ["a"] and list((tmp_path / "a").iterdir()) == []


def test_a_folder_that_cannot_be_made_is_an_input_error(tmp_path: Path, monkeypatch) -> None:
    import tempfile

    def refuse(*_a: object, **_k: object) -> str:
        raise PermissionError(13, "Permission denied")

    monkeypatch.setattr(tempfile, "mkdtemp", refuse)
    with pytest.raises(InputError) as info, output_dir(tmp_path / "x" / "scn"):
        pass
    assert info.value.field == "out" and "Permission denied" in str(info.value)
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("umask", [0o022, 0o027, 0o002, 0o077])
def test_output_folders_honour_the_umask(tmp_path: Path, umask: int) -> None:
    old = os.umask(umask)
    try:
        with output_dir(tmp_path / "new" / "scn") as tmp:
            _write(tmp, "x")
    finally:
        os.umask(old)
    for folder in (tmp_path / "new", tmp_path / "new" / "scn", tmp_path / "new" / "scn" / "sub"):
        assert stat.S_IMODE(folder.stat().st_mode) == 0o777 & ~umask, folder
    assert stat.S_IMODE((tmp_path / "new" / "scn" / "data.txt").stat().st_mode) == 0o666 & ~umask


def test_clean_stale_without_a_parent_is_a_no_op(tmp_path: Path) -> None:
    clean_stale(tmp_path / "missing" / "scn")
    assert list(tmp_path.iterdir()) == []  # nothing made where nothing was


def test_force_replaces_only_a_folder_agrinav_wrote(tmp_path: Path) -> None:
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "thesis.tex").write_text("years of work")
    with pytest.raises(InputError, match="not written by agrinav"), output_dir(mine, True):
        pass
    assert (mine / "thesis.tex").read_text() == "years of work"
    out = tmp_path / "scn"
    with output_dir(out) as tmp:
        _write(tmp, "old")
    assert (out / atomic.MARKER).is_file()  # what agrinav writes carries the marker
    with output_dir(out, overwrite=True) as tmp:
        _write(tmp, "new")
    assert (out / "data.txt").read_text() == "new" and (out / atomic.MARKER).is_file()


def test_force_replaces_only_output_of_the_same_kind(tmp_path: Path) -> None:
    """A policy export with --force must not replace a scenario folder (it did, leaving only
    the policy); a folder of the same kind, or marked before kinds were named, is replaced."""
    scn = tmp_path / "scn"
    with output_dir(scn, kind="scenario") as tmp:
        _write(tmp, "plants")
    assert atomic.marked_kind(scn) == "scenario"
    with pytest.raises(InputError, match="holds agrinav's scenario output; this command "
                       "replaces only policy export output"):  # fmt: skip
        with output_dir(scn, True, kind="policy export"):
            pass
    assert (scn / "data.txt").read_text() == "plants"
    with output_dir(scn, True, kind="scenario") as tmp:
        _write(tmp, "again")
    assert (scn / "data.txt").read_text() == "again"
    (scn / atomic.MARKER).write_text("Written by agrinav; a later run with --force may replace.\n")
    with output_dir(scn, True, kind="tune") as tmp:  # an older marker names no kind
        _write(tmp, "tuned")
    assert atomic.marked_kind(scn) == "tune"


@pytest.mark.parametrize("where", [".", "..", "~", "/"])
def test_force_never_replaces_the_current_home_or_root_folder(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, where: str
) -> None:
    cwd = tmp_path / "home" / "project"
    cwd.mkdir(parents=True)
    (cwd / "notes.txt").write_text("mine")
    for d in (cwd, cwd.parent):
        (d / atomic.MARKER).write_text("")  # even a marker (copied by hand) does not allow it
    monkeypatch.chdir(cwd)
    monkeypatch.setenv("HOME", str(cwd.parent))
    with (
        pytest.raises(InputError, match="never replaced"),
        output_dir(os.path.expanduser(where), overwrite=True),
    ):
        pass
    assert (cwd / "notes.txt").read_text() == "mine"


def test_names_the_file_system_cannot_hold_are_refused_before_anything_is_made(
    tmp_path: Path,
) -> None:
    """A name past NAME_MAX (with the temporary folder's tags) or a path past PATH_MAX is one
    InputError naming the limit, not errno 36 from a stat or a mkdir."""
    name_max = os.pathconf(tmp_path, "PC_NAME_MAX")
    longest = name_max - atomic.TMP_RESERVE
    with output_dir(tmp_path / ("a" * longest)) as tmp:  # the longest name that fits
        (tmp / "f").write_text("x")
    assert (tmp_path / ("a" * longest) / "f").is_file()
    too_long = [
        (tmp_path / ("b" * (longest + 1)), f"at most {longest} are allowed"),
        (tmp_path / ("c" * (name_max + 1)) / "x", f"at most {name_max} are allowed"),
        (tmp_path.joinpath(*["d" * 200] * 21), "at most 4095 are allowed"),
    ]
    for out, limit in too_long:
        with pytest.raises(InputError) as info, output_dir(out):
            pass
        assert info.value.field == "out" and limit in str(info.value)
    assert [p.name for p in tmp_path.iterdir()] == ["a" * longest]


@pytest.mark.parametrize("name", ["results\n", "a\tb", "esc\x1b[31m", "del\x7f"])
def test_control_characters_in_a_new_name_are_refused(tmp_path: Path, name: str) -> None:
    """A pasted path with a trailing newline made a folder no listing shows as typed."""
    for out in (tmp_path / name, tmp_path / name / "inner"):
        with pytest.raises(InputError, match="control character"), output_dir(out):
            pass
        with pytest.raises(InputError, match="control character"):
            atomic.check_creatable(out, "--out")
    assert list(tmp_path.iterdir()) == []


def test_control_characters_in_an_existing_parent_are_left_alone(tmp_path: Path) -> None:
    """Only the names still to be made are checked: the user's folder is theirs."""
    parent = tmp_path / "odd\tfolder"
    parent.mkdir()
    atomic.check_creatable(parent / "out", "--out")


def test_a_symbolic_link_as_out_is_refused(tmp_path: Path) -> None:
    """Replacing it swapped the link itself for a folder and left a temporary link behind."""
    target = tmp_path / "target"
    with output_dir(target) as tmp:
        (tmp / "f").write_text("x")
    link = tmp_path / "link"
    link.symlink_to(target)
    (tmp_path / "dangling").symlink_to(tmp_path / "nowhere")
    for out in (link, tmp_path / "dangling"):
        with pytest.raises(InputError, match="symbolic link"), output_dir(out, overwrite=True):
            pass
    assert link.is_symlink() and (target / "f").is_file()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["dangling", "link", "target"]


def test_an_empty_folder_is_taken_as_new_but_the_current_one_never(
    tmp_path: Path, monkeypatch
) -> None:
    out = tmp_path / "made-ahead"
    out.mkdir()
    with output_dir(out) as tmp:  # no --force needed: nothing in it to lose
        _write(tmp, "new")
    assert (out / "data.txt").read_text() == "new"
    empty = tmp_path / "here"
    empty.mkdir()
    monkeypatch.chdir(empty)
    for force in (False, True):
        with pytest.raises(InputError, match="current, home or root"), output_dir(".", force):
            pass
    assert list(empty.iterdir()) == []
