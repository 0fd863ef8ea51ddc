"""Built-in network kinds; importing this package registers them (see langtraj.synth.network).

Modules are imported in this order so `kind_names()` lists the kinds from single junctions to the
random city.

See docs/data.md.
"""

from __future__ import annotations

import importlib

KIND_MODULES: tuple[str, ...] = ("intersections", "roundabout", "highway", "arterial", "zebra", "city")

for _module in KIND_MODULES:
    importlib.import_module(f"{__name__}.{_module}")
