"""The studio's state is a command line: the page's spec is the CLI's, value for value."""

from __future__ import annotations

import shlex

import pytest
from shapely.geometry import Polygon

from baselines.cli import build_parser
from baselines.scenario_spec import spec_from_args
from baselines.studio.session import Session, field_file, yaml_value
from scenario_gen.errors import InputError
from scenario_gen.schema import field_rows, parse_yaml
from scenario_gen.spec import ScenarioSpec


def _cli_spec(command: str) -> ScenarioSpec:
    argv = shlex.split(command)
    assert argv[:2] == ["agrinav", "scenario"]
    spec: ScenarioSpec = spec_from_args(build_parser().parse_args(argv[1:]))
    return spec


def test_the_copied_command_makes_the_pages_spec() -> None:
    s = Session(preset="narrow-rows", seed=7)
    s.set("layout.jitter_lateral", 1e-05)  # YAML 1.1 reads "1e-05" as a string
    s.set("layout.row_angle_deg", 12.5)
    s.set("furrows.enabled", False)
    s.set("furrows.profile", "trapezoid")
    s.set("name", "my field: 'north' #2")
    s.set("route.first_lane", 3)
    s.set("crop.growth", 0.25)
    s.set_field(Polygon([(-84.2, 36.6), (-84.1998, 36.6), (-84.1998, 36.6003), (-84.2, 36.6)]))
    command = s.command("runs/x", force=True)
    assert "--force" in command and "--field runs/x.field.geojson" in command
    assert _cli_spec(command) == s.spec(str(field_file("runs/x")))
    assert s.spec().layout.jitter_lateral == 1e-05


@pytest.mark.parametrize("out", ["", "   ", "/", ".", "runs/.."])
def test_an_output_folder_with_no_name_is_refused_in_the_command_box(out: str) -> None:
    """With a drawn field, "/" was a ValueError from pathlib in the page's command box."""
    s = Session(seed=1)
    s.set_field(Polygon([(-84.2, 36.6), (-84.1998, 36.6), (-84.1998, 36.6003), (-84.2, 36.6)]))
    with pytest.raises(InputError, match="a folder path"):
        s.command(out, force=False)


def test_set_checks_like_the_cli_and_keeps_the_last_good_value() -> None:
    s = Session()
    s.set("layout.row_spacing", 0.8)
    with pytest.raises(InputError) as e:
        s.set("layout.row_spacing", 0.01)
    assert e.value.field == "layout.row_spacing" and "[0.05, 50]" in str(e.value)
    assert s.spec().layout.row_spacing == 0.8
    with pytest.raises(InputError) as e:
        s.set("crop.stage", 9)  # a cross-field check: corn has 5 stages
    assert e.value.field == "crop.stage"
    with pytest.raises(InputError):
        s.set("layout.no_such_key", 1)
    s.set("layout.row_spacing", s.base().layout.row_spacing)  # back to the preset's value
    assert "layout.row_spacing" not in s.overrides


def test_preset_switch_drops_overrides() -> None:
    s = Session()
    s.set("layout.row_spacing", 0.9)
    s.set_preset("paper-p2")
    assert s.overrides == {} and s.spec().layout.row_spacing == 2.0
    with pytest.raises(InputError):
        s.set_preset("nope")


@pytest.mark.parametrize(
    "value", [0.1, 1e-05, 2.5e10, -3, True, None, "sine", "yes", "a: b", [1.0, 2.5]]
)
def test_yaml_value_round_trips(value: object) -> None:
    assert parse_yaml(yaml_value(value), "v") == value


def test_every_spec_field_has_a_widget_or_a_named_owner() -> None:
    pytest.importorskip("nicegui")
    from baselines.studio.widgets import NOT_IN_FORM, SECTIONS, rows

    shown = {r[0] for section, _ in (*SECTIONS, ("name", "")) for r in rows(section)}
    every = {r[0] for r in field_rows(ScenarioSpec)}
    assert shown | NOT_IN_FORM == every and not shown & NOT_IN_FORM


def test_a_range_field_is_edited_as_text_and_read_as_a_list() -> None:
    """Fields holding a range ([low, high]) get a text widget: the page sends "[20, 40]"."""
    from baselines.studio.widgets import as_text, is_sequence, parse
    from scenario_gen.schema import field_info

    tp = field_info(ScenarioSpec, "layout.curve_radius")[0]  # type: ignore[index]
    assert is_sequence(tp) and not is_sequence(field_info(ScenarioSpec, "crop.stage")[0])  # type: ignore[index]
    value = parse("layout.curve_radius", "[20, 40]")
    assert value == [20, 40] and as_text((20.0, 40.0)) == "[20.0, 40.0]"
    s = Session()
    s.set("layout.curve_radius", value)
    assert list(s.spec().layout.curve_radius) == [20.0, 40.0]


def test_a_busy_port_or_a_file_as_workspace_is_refused_before_the_server_starts(
    tmp_path, capsys
) -> None:
    """Both used to start (or half-start: the address printed, then uvicorn's error and exit
    3); now one line, exit 2, no address printed."""
    import socket

    from baselines.cli import main

    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        port = busy.getsockname()[1]
        assert main(["studio", "--port", str(port), "--workspace", str(tmp_path)]) == 2
    out, err = capsys.readouterr()
    assert "--port" in err and "free port" in err and "studio on http" not in out
    afile = tmp_path / "afile.txt"
    afile.write_text("x")
    assert main(["studio", "--workspace", str(afile)]) == 2
    assert "--workspace" in capsys.readouterr().err
