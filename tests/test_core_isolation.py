"""The core (``cartan/``) knows no medium and never imports a plugin package."""

from __future__ import annotations

import ast
import pathlib
import subprocess
import sys

ROOT = pathlib.Path(__file__).resolve().parents[1]
CORE = ROOT / "cartan"


def _plugin_packages() -> set[str]:
    names = set()
    for base in (ROOT / "plugins", ROOT / "verification"):
        if base.is_dir():
            names |= {p.name for p in base.iterdir() if (p / "__init__.py").exists()}
    return names | {"cartan_verification"}


def _imports(path: pathlib.Path) -> set[str]:
    tree = ast.parse(path.read_text(), filename=str(path))
    found = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found |= {a.name.split(".")[0] for a in node.names}
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            found.add(node.module.split(".")[0])
        elif isinstance(node, ast.Call) and getattr(node.func, "attr", getattr(node.func, "id", "")) in {
            "import_module", "__import__"
        }:
            for arg in node.args[:1]:
                if isinstance(arg, ast.Constant) and isinstance(arg.value, str):
                    found.add(arg.value.split(".")[0])
    return found


def test_core_source_never_imports_plugins():
    plugin_pkgs = _plugin_packages()
    offenders = {}
    for path in CORE.rglob("*.py"):
        bad = _imports(path) & plugin_pkgs
        if bad:
            offenders[str(path.relative_to(ROOT))] = sorted(bad)
    assert not offenders, f"core modules import plugin packages: {offenders}"


def test_importing_every_core_module_loads_no_plugin():
    code = (
        "import importlib, pkgutil, sys, cartan\n"
        "for m in pkgutil.walk_packages(cartan.__path__, 'cartan.'):\n"
        "    importlib.import_module(m.name)\n"
        "print('\\n'.join(sorted(sys.modules)))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], check=True, capture_output=True, text=True).stdout
    loaded = set(out.split())
    plugin_pkgs = _plugin_packages()
    assert not {m.split(".")[0] for m in loaded} & plugin_pkgs


def test_core_has_no_medium_names():
    """No branch on a medium's name in the core: registered media names never appear there."""
    medium_words = ["cosserat", "sigma-model", "sphere-rod", "filament", "kirchhoff", "relativistic-rod"]
    offenders = []
    for path in CORE.rglob("*.py"):
        text = path.read_text().lower()
        for word in medium_words:
            for line in text.splitlines():
                stripped = line.strip()
                if word in stripped and not stripped.startswith("#") and ("==" in stripped or "if " in stripped):
                    offenders.append(f"{path.name}: {stripped}")
    assert not offenders, offenders
