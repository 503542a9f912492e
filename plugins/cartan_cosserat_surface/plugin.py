"""Hook implementations of the ``cartan_cosserat_surface`` plugin (entry point ``cartan_cosserat_surface.plugin``)."""

from __future__ import annotations
