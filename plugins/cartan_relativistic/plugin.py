"""Hook implementations of the ``cartan_relativistic`` plugin (entry point ``cartan_relativistic.plugin``)."""

from __future__ import annotations
