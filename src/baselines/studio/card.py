"""The scenario card: name, seed, output folder, and the buttons (generate and save, export,
run a policy) with the equivalent ``agrinav scenario`` command."""

from __future__ import annotations

import copy
from typing import Any, Protocol

from nicegui import run, ui

from scenario_gen.errors import InputError

from . import actions
from .session import Session
from .shared import Studio
from .widgets import Form


class Host(Protocol):
    """What the card needs from its page (``app.Page``)."""

    s: Session
    form: Form
    studio: Studio

    def on_seed(self, e: Any) -> None: ...

    def error_label(self, where: str) -> Any: ...


class ScenarioCard:
    """The lower part of the side panel; it reads the page's session and shows its errors."""

    def __init__(self, page: Host, values: dict[str, Any]) -> None:
        self.page, self.s, self.form, self.studio = page, page.s, page.form, page.studio
        self.saved: str | None = None
        with ui.card().classes("w-full"):
            ui.label("Scenario").classes("text-subtitle1")
            self.form.section("name", values)
            self.seed = ui.number("seed", value=self.s.seed, on_change=page.on_seed).classes(
                "w-full"
            )
            self.seed.without_auto_validation()
            self.seed.props.update(
                {"data-key": "seed", "hint": "generation seed · an integer in [0, 2**63)"}
            )
            self.form.widgets["seed"] = self.seed
            # the folder follows the scenario's name until the user types one of their own
            self._auto_out = str(self.studio.workspace / self.s.spec().name)
            self.out = ui.input(
                "output folder", value=self._auto_out, on_change=lambda _: self.update_command()
            ).classes("w-full")
            self.out.without_auto_validation()
            self.out.props.update({"data-key": "out"})
            self.form.widgets["out"] = self.out
            self.overwrite = ui.switch("overwrite", on_change=lambda _: self.update_command())
            with ui.row():
                ui.button("generate and save", on_click=self.on_generate).props(
                    'data-key="generate"'
                )
            self.form.labels["general"] = page.error_label("general")
            self.result = ui.label("").classes("text-caption").props('data-key="result"')
            ui.label("equivalent command").classes("text-caption")
            self.command = (
                ui.code("", language="bash").classes("w-full").props('data-key="command"')
            )
            ui.separator()
            formats = actions.export_formats()
            with ui.row().classes("items-center"):
                self.fmt = ui.select(
                    list(formats), value=formats[0] if formats else None, label="export"
                )
                self.fmt.classes("w-40").props('data-key="export-format"')
                self.fmt.without_auto_validation()
                b = ui.button("export", on_click=self.on_export).props('data-key="export"')
                if not formats:
                    self.fmt.disable()
                    b.disable()
                    b.tooltip("this install has no exporter (agrinav export)")
            self.form.widgets["export"] = self.fmt
            ui.separator()
            with ui.row().classes("items-center"):
                self.policy = ui.select(list(actions.POLICIES), value="rpp", label="policy")
                self.policy.classes("w-40").props('data-key="policy"')
                self.policy.without_auto_validation()
                ui.button("run", on_click=self.on_run).props('data-key="run"')
            self.form.widgets["policy"] = self.policy
            self.form.labels["scenario"] = page.error_label("scenario")
            self.run_box = ui.column().classes("w-full")
        self.update_command()

    def update_command(self) -> None:
        try:
            if self.out.value == self._auto_out:
                self._auto_out = str(self.studio.workspace / self.s.spec().name)
                self.out.set_value(self._auto_out)  # no-op when the name is the same
            self.command.set_content(self.s.command(self.out.value, bool(self.overwrite.value)))
        except (InputError, AttributeError):
            pass  # built before the scenario card exists, or a refused value: keep the last

    async def on_generate(self) -> None:
        self.result.set_text("")
        if self.form.input_errors:
            keys = ", ".join(sorted(self.form.input_errors))
            self.form.show(InputError("general", keys, "fix this input first; nothing was written"))
            return
        session, out = copy.deepcopy(self.s), str(self.out.value or "")
        self.result.set_text("generating…")
        try:
            summary = await run.io_bound(
                actions.generate_and_save,
                session,
                out,
                bool(self.overwrite.value),
                self.studio.workspace,
            )
        except InputError as exc:
            self.result.set_text("nothing was written")
            self.form.show(exc)
            return
        assert summary is not None  # io_bound returns None only when the app is shutting down
        self.form.clear_shown()
        self.saved = out
        self.result.set_text(
            f"saved {out}: {summary['plants']:,} plants, {summary['rows']} rows, "
            f"relief {summary['relief_m']} m"
            + (f", slope {summary['slope_deg']['median']}°" if summary.get("slope_deg") else "")
            + (f"; field in {summary['field_file']}" if summary["field_file"] else "")
        )

    async def on_export(self) -> None:
        if self.saved is None:
            self.form.show(InputError("scenario", None, "generate and save the scenario first"))
            return
        out = f"{self.saved}-{self.fmt.value}"
        self.result.set_text(f"exporting {self.fmt.value}…")
        try:
            await run.io_bound(
                actions.export, self.saved, str(self.fmt.value), out, bool(self.overwrite.value)
            )
        except InputError as exc:
            self.result.set_text("nothing was written")
            self.form.show(exc)
            return
        self.result.set_text(f"exported {self.fmt.value} to {out}")

    async def on_run(self) -> None:
        if self.saved is None:
            self.form.show(InputError("scenario", None, "generate and save the scenario first"))
            return
        policy = str(self.policy.value)
        out = f"{self.saved}-run-{policy.replace(':', '-')}"
        self.run_box.clear()
        with self.run_box:
            ui.spinner()
            ui.label(f"running {policy} on {self.saved}…").classes("text-caption")
        try:
            rec = await run.io_bound(
                actions.run_policy, self.saved, policy, out, overwrite=bool(self.overwrite.value)
            )
        except InputError as exc:
            self.run_box.clear()
            self.form.show(exc)
            return
        assert rec is not None
        self.run_box.clear()
        with self.run_box:
            ui.image(rec["figure"]).classes("w-full").props(
                'data-key="trajectory" loading=eager fit=contain'
            )
            ui.table(
                columns=[
                    {"name": "metric", "label": "metric", "field": "metric"},
                    {"name": "value", "label": "value", "field": "value"},
                ],
                rows=actions.metrics_rows(rec),
            ).props('dense flat data-key="metrics"').classes("w-full")
