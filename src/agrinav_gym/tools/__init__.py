"""Offline tools: fits whose output is a data file the runtime reads (``proxy_fit`` writes
``render/proxy_fit.json``). They may use the whole package; nothing at run time imports them."""
