"""The field studio: a local web page to draw a field on the terrain, tune it live and run it.

``agrinav studio`` serves one page on 127.0.0.1 (NiceGUI: Leaflet and leaflet-draw come with
the installed package, so nothing is fetched from the internet). The modules are small and only
``app`` imports NiceGUI:

* ``fields``: drawn polygons (holes by containment) to and from GeoJSON, validated;
* ``session``: the studio's state (base spec, overrides, field, seed) and the CLI command;
* ``preview``: the live layout preview, computed with the generator's own functions;
* ``layers``: the terrain as map layers (hillshade and contours in lat/lon, elevation readout);
* ``actions``: generate and save, export, run a policy;
* ``widgets`` and ``app``: the page, its form generated from the config metadata.
"""
