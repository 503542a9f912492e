"""Hook implementations of the ``cartan_cosserat_solid`` plugin (entry point ``cartan_cosserat_solid.plugin``)."""

from __future__ import annotations
