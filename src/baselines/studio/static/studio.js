// AgriNav studio: the map side of the page. Served from the package; uses the Leaflet and
// leaflet-draw that NiceGUI ships (window.L), nothing from the network.
"use strict";

window.studio = (function () {
  const S = {
    map: null,
    drawn: null, // leaflet-draw's FeatureGroup: the editable field polygons
    plants: null,
    route: null,
    outline: null,
    overlays: {},
    lastChange: null, // performance.now() of the last parameter or field change
    latencies: [], // change -> redrawn preview, ms
    arrivals: [], // change -> preview data received from the server, ms
    drawnAt: 0,
    shown: 0, // previews drawn
  };

  // One canvas for every plant: thousands of dots in one pass, no object per plant. Built on
  // first use: NiceGUI loads Leaflet (window.L) only when the map component mounts.
  const dotLayer = (pane) => new (L.Layer.extend({
    initialize(pane) {
      this._pane = pane;
      this._data = { plants: [], weeds: [], dot_m: 0.2, obstacles: {}, obstacle_style: {} };
    },
    onAdd(map) {
      this._canvas = L.DomUtil.create("canvas", "leaflet-zoom-hide studio-dots");
      map.getPane(this._pane).appendChild(this._canvas);
      map.on("moveend zoomend resize viewreset", this._redraw, this);
      this._redraw();
    },
    onRemove(map) {
      L.DomUtil.remove(this._canvas);
      map.off("moveend zoomend resize viewreset", this._redraw, this);
    },
    setData(d) {
      this._data = d;
      if (this._map) this._redraw();
    },
    _redraw() {
      const map = this._map;
      const size = map.getSize();
      const dpr = window.devicePixelRatio || 1;
      const c = this._canvas;
      L.DomUtil.setPosition(c, map.containerPointToLayerPoint([0, 0]));
      c.width = size.x * dpr;
      c.height = size.y * dpr;
      c.style.width = size.x + "px";
      c.style.height = size.y + "px";
      const ctx = c.getContext("2d");
      ctx.setTransform(dpr, 0, 0, dpr, 0, 0);
      const lat0 = map.getCenter().lat;
      const mPerPx = (40075016.686 * Math.cos((lat0 * Math.PI) / 180)) / Math.pow(2, map.getZoom() + 8);
      const r = Math.max(1.2, (0.5 * this._data.dot_m) / mPerPx);
      const draw = (arr, colour) => {
        ctx.fillStyle = colour;
        ctx.beginPath();
        for (let i = 0; i < arr.length; i += 2) {
          const p = map.latLngToContainerPoint([arr[i], arr[i + 1]]);
          if (p.x < -r || p.y < -r || p.x > size.x + r || p.y > size.y + r) continue;
          ctx.moveTo(p.x + r, p.y);
          ctx.arc(p.x, p.y, r, 0, 2 * Math.PI);
        }
        ctx.fill();
      };
      draw(this._data.plants, "#1f8a2a");
      draw(this._data.weeds, "#ff5a1f");
      // Obstacles: each footprint (4 lat/lon corners) as its own quadrilateral, outlined so a
      // thin fallen stalk still shows as a line; one smaller than MIN px becomes a MIN-px
      // square on its centre (a 10 cm stone is a fraction of a pixel at the zoom a field fills).
      const MIN = 4;
      for (const [kind, flat] of Object.entries(this._data.obstacles || {})) {
        // fill, outline, width per kind: the server's studio.preview.OBSTACLE_STYLE
        const [fill, edge, width] = (this._data.obstacle_style || {})[kind] || ["#888888", "#000000", 1];
        ctx.fillStyle = fill;
        ctx.strokeStyle = edge;
        ctx.lineWidth = width;
        ctx.beginPath();
        for (let i = 0; i < flat.length; i += 8) {
          const pts = [0, 2, 4, 6].map((k) => map.latLngToContainerPoint([flat[i + k], flat[i + k + 1]]));
          const cx = (pts[0].x + pts[2].x) / 2;
          const cy = (pts[0].y + pts[2].y) / 2;
          const span = Math.hypot(pts[0].x - pts[2].x, pts[0].y - pts[2].y);
          if (cx < -span - MIN || cy < -span - MIN || cx > size.x + span + MIN || cy > size.y + span + MIN) continue;
          if (span < MIN) {
            ctx.rect(cx - MIN / 2, cy - MIN / 2, MIN, MIN);
          } else {
            ctx.moveTo(pts[0].x, pts[0].y);
            for (let k = 1; k < 4; k++) ctx.lineTo(pts[k].x, pts[k].y);
            ctx.closePath();
          }
        }
        ctx.fill();
        ctx.stroke();
      }
    },
  }))(pane);

  function markChange() {
    S.lastChange = performance.now();
  }

  function emitField() {
    markChange();
    setTimeout(() => emitEvent("studio_field", S.drawn.toGeoJSON()), 0);
  }

  S.init = function (elementId) {
    return new Promise((resolve) => {
      const tick = () => {
        const el = getElement(elementId);
        if (!el || !el.map) return setTimeout(tick, 50);
        const map = (S.map = el.map);
        map.eachLayer((l) => {
          if (l instanceof L.FeatureGroup && !S.drawn) S.drawn = l;
        });
        map.createPane("terrain").style.zIndex = 250;
        map.createPane("dots").style.zIndex = 450;
        S.plants = dotLayer("dots").addTo(map);
        S.route = L.layerGroup().addTo(map);
        S.outline = L.layerGroup().addTo(map);
        for (const ev of ["draw:created", "draw:edited", "draw:deleted"]) map.on(ev, emitField);
        const form = document.getElementById("studio-form");
        if (form) {
          form.addEventListener("input", markChange, true);
          form.addEventListener("change", markChange, true);
        }
        resolve(true);
      };
      tick();
    });
  };

  // A terrain layer (hillshade and contours) below everything else.
  S.overlay = function (name, url, bounds, opacity) {
    if (S.overlays[name]) S.map.removeLayer(S.overlays[name]);
    S.overlays[name] = L.imageOverlay(url, bounds, { pane: "terrain", opacity: opacity }).addTo(S.map);
  };

  S.fit = function (bounds) {
    S.map.fitBounds(bounds, { animate: false });
  };

  // The preview: plants, weeds, obstacles, route and field outline, then the time since the
  // change.
  S.show = function (d) {
    if (S.lastChange !== null) S.arrivals.push(performance.now() - S.lastChange);
    S.plants.setData({
      plants: d.plants,
      weeds: d.weeds,
      dot_m: d.dot_m,
      obstacles: d.obstacles,
      obstacle_style: d.obstacle_style,
    });
    S.route.clearLayers();
    for (const [tag, flat] of d.route) {
      const pts = [];
      for (let i = 0; i < flat.length; i += 2) pts.push([flat[i], flat[i + 1]]);
      L.polyline(pts, {
        color: tag === "furrow" ? "#e0121b" : "#d31ad6",
        weight: 2.5,
        interactive: false,
      }).addTo(S.route);
    }
    S.outline.clearLayers();
    if (d.outline) {
      const rings = d.field.map((flat) => {
        const pts = [];
        for (let i = 0; i < flat.length; i += 2) pts.push([flat[i], flat[i + 1]]);
        return pts;
      });
      L.polygon(rings, { color: "#ffffff", weight: 2, dashArray: "6 4", fill: false, interactive: false }).addTo(S.outline);
    }
    const changed = S.lastChange;
    requestAnimationFrame(() =>
      requestAnimationFrame(() => {
        S.drawnAt = performance.now();
        S.shown += 1;
        const el = document.getElementById("studio-redraw");
        if (changed !== null) {
          const ms = S.drawnAt - changed;
          S.latencies.push(ms);
          if (el) el.textContent = "redrawn " + ms.toFixed(0) + " ms after the change";
          S.lastChange = null;
        }
      })
    );
  };

  // Replace the editable polygons (a loaded GeoJSON, or clearing them).
  S.setField = function (geojson) {
    S.drawn.clearLayers();
    if (geojson) {
      L.geoJSON(geojson).eachLayer((l) => {
        if (l instanceof L.Polygon) S.drawn.addLayer(L.polygon(l.getLatLngs(), l.options));
      });
    }
  };

  S.markChange = markChange;
  return S;
})();
