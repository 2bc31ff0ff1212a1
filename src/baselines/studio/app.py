"""The studio page (NiceGUI): the map, the generated form, the buttons; one per browser tab.

Everything the page loads comes from the installed NiceGUI package (Vue, Quasar, Leaflet,
leaflet-draw, fonts) or from this package (``static/studio.js``, the terrain images rendered
here); the default OpenStreetMap layer NiceGUI adds is removed, and an online base map is only
added when the user ticks it.
"""

from __future__ import annotations

import asyncio
import json
import tempfile
from pathlib import Path
from typing import Any

from nicegui import app, background_tasks, events, run, ui
from starlette.responses import Response

from scenario_gen import crops, preset_names
from scenario_gen.errors import InputError
from scenario_gen.generate import growth_of
from scenario_gen.preview import OBSTACLE_LABELS
from scenario_gen.schema import parse_json
from scenario_gen.sources import MESH_SUFFIXES

from . import actions, fields, guard, layers
from .card import ScenarioCard
from .preview import Preview, layout_preview
from .shared import Studio
from .widgets import SECTIONS, Form

#: what the field upload takes (a GeoJSON object, whatever the file is called)
GEOJSON_SUFFIXES = (".geojson", ".json")

STATIC = Path(__file__).parent / "static"
OSM = "https://tile.openstreetmap.org/{z}/{x}/{y}.png"
DETAIL_PAD_M = 60.0  # terrain shown in detail around the field


class Page:
    """One tab: its own session, form and map."""

    def __init__(self, studio: Studio) -> None:
        self.studio = studio
        self.s = studio.new_session()
        self.form = Form(self.on_change)
        self.preview: Preview | None = None
        self.detail_box: tuple[float, float, float, float] | None = None
        self._pending_error: InputError | None = None

    # ------------------------------------------------------------------ layout
    async def build(self) -> None:
        ui.add_head_html('<script src="/studio/static/studio.js"></script>')
        ui.add_css(
            ".studio-side .q-field__bottom{white-space:normal}"
            ".studio-side .q-scrollarea__content{width:100%}"
            ".nicegui-code pre{white-space:pre-wrap;word-break:break-all}"
        )
        spec = self.s.spec()
        values = _flat(spec.to_dict())
        first = self._safe_preview()
        with ui.header().classes("items-center gap-4 bg-green-9 q-py-xs"):
            ui.label("AgriNav studio").classes("text-h6")
            ui.label(self.studio.elevation(self.s).label).classes("text-caption")
            ui.space()
            ui.select(
                preset_names(), value=self.s.preset, label="preset", on_change=self.on_preset
            ).props('dense dark options-dark=false data-key="preset"').classes("w-40")
            self.online = ui.checkbox("online base map", on_change=self.on_online).props("dark")
            self.online.tooltip("OpenStreetMap tiles from the internet; everything else is local")
        with ui.row().classes("w-full no-wrap gap-2").style("height: calc(100vh - 64px)"):
            with ui.column().classes("h-full gap-1").style("flex: 1 1 62%"):
                centre = _centre(first)
                self.map = (
                    ui.leaflet(
                        center=centre,
                        zoom=18,
                        draw_control={
                            "draw": {
                                "polygon": True,
                                "rectangle": True,
                                "polyline": False,
                                "circle": False,
                                "marker": False,
                                "circlemarker": False,
                            },
                            "edit": {"edit": True, "remove": True},
                        },
                        options={"maxZoom": 24, "zoomSnap": 0.25, "preferCanvas": False},
                    )
                    .classes("w-full")
                    .style("height: calc(100vh - 130px)")
                )
                self.map.clear_layers()  # NiceGUI adds an online OpenStreetMap layer by default
                with ui.row().classes("w-full gap-4 text-caption items-center"):
                    self.counts = ui.label("").props('data-key="counts"')
                    self.cursor = ui.label("move over the map for lat, lon, elevation")
                    ui.html('<span id="studio-redraw"></span>')
            with ui.scroll_area().classes("h-full studio-side").style("flex: 1 1 38%"):
                self._side(values)
        self.map.on("map-mousemove", self.on_cursor, args=["latlng"], throttle=0.08)
        ui.on("studio_field", self.on_field)
        self.client = ui.context.client
        await self.client.connected(timeout=30)
        await self.map.initialized()
        await ui.run_javascript(f"studio.init({self.map.id})", timeout=20)
        self.show_layer("overview", self.studio.elevation(self.s).extent, 700)
        if first is not None:
            self.draw(first)
            self.fit(first)
            self.detail(first)
        elif self._pending_error is not None:
            self.form.show(self._pending_error)

    def _side(self, values: dict[str, Any]) -> None:
        with ui.column().classes("w-full gap-1 q-pa-sm").props('id="studio-form"'):
            with ui.card().classes("w-full"):
                ui.label("Field").classes("text-subtitle1")
                ui.label(
                    "Draw a polygon or rectangle on the map (polygons drawn inside another are "
                    "holes), edit or delete it with the toolbar, or load a GeoJSON."
                ).classes("text-caption")
                self.form.labels["field"] = self.error_label("field")
                with ui.row().classes("items-center"):
                    ui.upload(
                        label="load GeoJSON",
                        auto_upload=True,
                        on_upload=self.on_geojson,
                        on_rejected=lambda: self._rejected("field", GEOJSON_SUFFIXES),
                        max_file_size=guard.MAX_BODY,
                    ).props(
                        f'accept="{",".join(GEOJSON_SUFFIXES)}" flat dense '
                        'data-key="upload-geojson"'
                    ).classes("w-56")
                    ui.button("clear field", on_click=self.on_clear_field).props("flat dense")
            for section, title in SECTIONS:
                exp = ui.expansion(title, value=section == "layout").classes("w-full")
                with exp.props(f'data-section="{section}"'):
                    self.form.labels[f"{section}."] = self.error_label(f"{section}.")
                    if section == "crop":
                        self._model_picker()
                    self.form.section(section, values)
            self.card = ScenarioCard(self, values)

    def error_label(self, where: str) -> Any:
        label = ui.label("").classes("text-negative text-caption").props(f'data-error="{where}"')
        label.set_visibility(False)
        return label

    def _model_picker(self) -> None:
        self.model = (
            ui.select(self._model_options(), value="", label="crop model", on_change=self.on_model)
            .classes("w-full")
            .props('data-key="crop.model"')
        )
        self.model.without_auto_validation()
        self.form.widgets["crop.model"] = self.model
        ui.upload(
            label="upload a model (.zip or mesh)",
            auto_upload=True,
            on_upload=self.on_model_upload,
            on_rejected=lambda: self._rejected("crop.model", (*MESH_SUFFIXES, ".zip")),
            max_file_size=guard.MAX_BODY,
        ).props(
            f'accept="{",".join((*MESH_SUFFIXES, ".zip"))}" flat dense data-key="upload-model"'
        ).classes("w-full")

    def _rejected(self, where: str, suffixes: tuple[str, ...]) -> None:
        """The browser refused a file before sending it (its type or size): say so, where the
        upload's own errors go, instead of nothing."""
        self.form.show(
            InputError(
                where,
                "the chosen file",
                f"allowed: {', '.join(suffixes)}, at most {guard.MAX_BODY // 2**20} MiB",
            ),
            sticky=True,
        )

    def _model_options(self) -> dict[str, str]:
        opts = {"": "built-in model of the species"}
        if self.studio.models_dir.is_dir():
            for p in sorted(self.studio.models_dir.iterdir()):
                if not p.name.startswith("."):
                    opts[str(p)] = p.name
        return opts

    # ------------------------------------------------------------------ map drawing
    def _safe_preview(self) -> Preview | None:
        try:
            return layout_preview(self.s.spec(), self.s.seed, self.s.field_geom, self.studio.sites)
        except InputError as exc:
            self._pending_error = exc
            return None

    def refresh(self) -> None:
        """Recompute the preview and redraw it (or show why it cannot be made)."""
        try:
            pv = layout_preview(self.s.spec(), self.s.seed, self.s.field_geom, self.studio.sites)
        except InputError as exc:
            self.form.show(exc)
            self.counts.set_text("preview not updated: fix the highlighted input")
            ui.run_javascript("studio.lastChange = null")
            return
        self.form.clear_shown()
        self.draw(pv)
        self.detail(pv)

    def draw(self, pv: Preview) -> None:
        self.preview = pv
        data = pv.payload()
        data["outline"] = self.s.field_geom is None
        ui.run_javascript(f"studio.show({json.dumps(data)})")
        shown = "" if pv.stride == 1 else f" (1 in {pv.stride} drawn)"
        obstacles = "".join(f"{len(v):,} {OBSTACLE_LABELS[k]} · " for k, v in pv.obstacles.items())
        self.counts.set_text(
            f"{pv.n_plants:,} plants{shown} · {pv.n_weeds:,} weeds · {obstacles}{pv.n_rows} rows · "
            f"{pv.area_m2:,.0f} m² · route {pv.route_m:.1f} m · "
            f"computed in {1000 * pv.seconds:.0f} ms"
        )
        # The command box re-renders highlighted code: let the map go out first.
        background_tasks.create(self._command_soon(), name="studio command")

    async def _command_soon(self) -> None:
        await asyncio.sleep(0.05)
        self.card.update_command()

    def fit(self, pv: Preview) -> None:
        south, west, north, east = _bbox(pv)
        ui.run_javascript(f"studio.fit([[{south}, {west}], [{north}, {east}]])")

    def show_layer(self, name: str, bbox: tuple[float, float, float, float], px: int) -> None:
        """Render a terrain layer in a worker thread and put it on the map when it is ready:
        a detail layer takes ≈0.5 s, which must not hold up the plant preview."""
        background_tasks.create(self._layer(name, bbox, px), name=f"studio layer {name}")

    async def _layer(self, name: str, bbox: tuple[float, float, float, float], px: int) -> None:
        elev = self.studio.elevation(self.s)
        layer = await run.io_bound(layers.render, elev, bbox, px)
        if layer is not None:
            url = self.studio.image_url(layer)
            bounds = [list(layer.bounds[0]), list(layer.bounds[1])]
            self.client.run_javascript(
                f"studio.overlay({json.dumps(name)}, {json.dumps(url)}, {bounds}, 0.9)"
            )

    def detail(self, pv: Preview) -> None:
        """Terrain in detail around the field, re-rendered when the field leaves it."""
        south, west, north, east = _bbox(pv)
        box = self.detail_box
        if (
            box is not None
            and box[0] <= west
            and box[1] <= south
            and box[2] >= east
            and box[3] >= north
        ):
            return
        self.detail_box = layers.around((west, south, east, north), DETAIL_PAD_M)
        self.show_layer("detail", self.detail_box, 800)

    # ------------------------------------------------------------------ events
    def on_change(self, key: str, value: Any) -> None:
        try:
            self.s.set(key, value)
        except InputError as exc:
            self.form.show(exc, sticky=True)
            self.counts.set_text("preview not updated: fix the highlighted input")
            ui.run_javascript("studio.lastChange = null")
            return
        self.form.clear_input(key)
        self.refresh()

    def on_seed(self, e: Any) -> None:
        v = e.value
        if v is None or not float(v).is_integer() or not 0 <= v < 2**63:
            self.form.show(InputError("seed", v, "allowed: an integer in [0, 2**63)"), sticky=True)
            return
        self.form.clear_input("seed")
        self.s.seed = int(v)
        self.refresh()

    def on_preset(self, e: Any) -> None:
        try:
            self.s.set_preset(str(e.value))
        except InputError as exc:
            self.form.show(exc)
            return
        for key in list(self.form.input_errors):
            self.form.clear_input(key)
        self.form.set_values(_flat(self.s.spec().to_dict()))
        self.refresh()
        if self.preview is not None and self.s.field_geom is None:
            self.fit(self.preview)

    def on_field(self, e: events.GenericEventArguments) -> None:
        try:
            geom = fields.combine(fields.polygons_of(e.args))
            self.s.set_field(geom)
        except InputError as exc:
            self.form.show(exc, sticky=True)
            self.counts.set_text("preview not updated: fix the field")
            ui.run_javascript("studio.lastChange = null")
            return
        self.form.clear_input("field")
        self.refresh()

    async def on_geojson(self, e: events.UploadEventArguments) -> None:
        try:
            data = parse_json(await e.file.read(), "field", e.file.name)
            # off the event loop: a file of thousands of polygons takes seconds to merge, and
            # every open tab would freeze meanwhile
            geom = await run.io_bound(fields.field_of, data)
            if geom is None:
                raise InputError("field", e.file.name, "holds no Polygon or MultiPolygon")
            self.s.set_field(geom)
        except InputError as exc:
            self.form.show(exc, sticky=True)
            return
        self.form.clear_input("field")
        ui.run_javascript(f"studio.setField({self.s.field_text})")
        self.refresh()
        if self.preview is not None:
            self.fit(self.preview)

    def on_clear_field(self) -> None:
        ui.run_javascript("studio.setField(null); studio.markChange()")
        self.s.set_field(None)
        self.form.clear_input("field")
        self.refresh()

    def on_cursor(self, e: events.GenericEventArguments) -> None:
        ll = e.args.get("latlng") if isinstance(e.args, dict) else None
        if not ll:
            return
        import numpy as np

        lat, lon = float(ll["lat"]), float(ll["lng"])
        z = float(self.studio.elevation(self.s)(np.array([lon]), np.array([lat]))[0])
        elev = "off the terrain" if not np.isfinite(z) else f"{z:.2f} m"
        self.cursor.set_text(f"lat {lat:.6f}, lon {lon:.6f} · elevation {elev}")

    def on_online(self, e: Any) -> None:
        if e.value:
            opts = {
                "maxZoom": 24,
                "maxNativeZoom": 19,
                "attribution": "© OpenStreetMap contributors",
            }
            layer = f"L.tileLayer({json.dumps(OSM)}, {json.dumps(opts)})"
            js = f"studio.base = {layer}.addTo(studio.map)"
        else:
            js = "if (studio.base) { studio.map.removeLayer(studio.base); studio.base = null; }"
        ui.run_javascript(js)

    def on_model(self, e: Any) -> None:
        self.on_change("crop.model", e.value or None)

    async def on_model_upload(self, e: events.UploadEventArguments) -> None:
        spec = self.s.spec()
        height = float(crops.species(spec.crop.species).height(growth_of(spec.crop)))
        with tempfile.TemporaryDirectory(prefix="agrinav-upload-") as tmp:
            path = Path(tmp) / "upload"
            await e.file.save(path)
            try:
                target = await run.io_bound(
                    actions.install_model, path, e.file.name, self.studio.models_dir, height
                )
            except InputError as exc:
                self.form.show(exc, sticky=True)
                return
        self.model.set_options(self._model_options(), value=str(target))


def _flat(d: dict[str, Any], prefix: str = "") -> dict[str, Any]:
    out: dict[str, Any] = {}
    for k, v in d.items():
        if isinstance(v, dict):
            out.update(_flat(v, f"{prefix}{k}."))
        else:
            out[f"{prefix}{k}"] = v
    return out


def _bbox(pv: Preview) -> tuple[float, float, float, float]:
    import numpy as np

    pts = np.concatenate([r.reshape(-1, 2) for r in pv.field])
    (south, west), (north, east) = pts.min(axis=0), pts.max(axis=0)
    return float(south), float(west), float(north), float(east)


def _centre(pv: Preview | None) -> tuple[float, float]:
    if pv is None:
        return (0.0, 0.0)
    south, west, north, east = _bbox(pv)
    return (0.5 * (south + north), 0.5 * (west + east))


def serve(studio: Studio, port: int, host: str = "127.0.0.1", token: str | None = None) -> None:
    """Serve the studio until interrupted (blocks); only the printed address can drive it
    (``guard.Guard``: Host, Origin, the per-launch token, body size, no framing)."""
    from nicegui import core

    token = token or guard.new_token()
    extra = () if host in ("127.0.0.1", "0.0.0.0", "::") else (host,)
    core.sio.eio.cors_allowed_origins = guard.allowed_origins(port, extra)
    app.add_middleware(guard.Guard, token=token, hosts=guard.allowed_hosts(port, extra), port=port)
    app.add_static_files("/studio/static", STATIC)

    @app.get("/studio/layer/{key}.png")
    def layer_png(key: str) -> Response:
        png = studio.images.get(key)
        return Response(png or b"", media_type="image/png", status_code=200 if png else 404)

    @ui.page("/")
    async def index() -> None:
        await Page(studio).build()

    print(f"AgriNav studio on http://{host}:{port}/?token={token} (Ctrl+C to stop)", flush=True)
    ui.run(
        host=host,
        port=port,
        title="AgriNav studio",
        reload=False,
        show=False,
        uvicorn_logging_level="warning",
        show_welcome_message=False,
    )
