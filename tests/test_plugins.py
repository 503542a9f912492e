"""The plugin system: entry points, registries, duplicate names, broken plugins."""

from __future__ import annotations

import importlib.metadata as md
import types
import warnings

import pytest

import cartan
from cartan import plugins


@pytest.fixture(autouse=True)
def _fresh_registry():
    plugins.reset_registry()
    yield
    plugins.reset_registry()


def _module(name: str, **hooks) -> types.ModuleType:
    mod = types.ModuleType(name)
    for hook, fn in hooks.items():
        setattr(mod, hook, cartan.hookimpl(fn))
    return mod


def test_builtin_groups_arrive_through_entry_points():
    reg = plugins.get_registry()
    groups = reg.table("groups")
    assert {"SO2", "SE2", "SO3", "SE3", "SO", "SO13", "Poincare"} <= set(groups)
    for entry in groups.values():
        assert entry.distribution == "cartan"
        assert entry.plugin == "cartan:groups"
    names = {ep.name for ep in md.entry_points(group="cartan")}
    assert "groups" in names


def test_group_factory_and_parameters():
    assert cartan.group("SE3").dim == 6
    so5 = cartan.group("SO", n=5)
    assert (so5.dim, so5.matrix_size) == (10, 5)
    with pytest.raises(cartan.RegistryError, match="unknown group 'SE4'.*SE3"):
        cartan.group("SE4")
    with pytest.raises(ValueError, match="n"):
        cartan.group("SO", n=1)


def test_third_party_plugin_registers_like_builtin():
    class Dummy:
        """A dummy medium."""

    mod = _module("cartan_dummy", cartan_register_media=lambda register: register("dummy-medium", Dummy))
    plugins.reset_registry([("cartan_dummy", mod)])
    assert cartan.registry("media")["dummy-medium"] is Dummy
    assert plugins.get_registry().table("media")["dummy-medium"].distribution == "local"


def test_duplicate_name_is_an_error():
    a = _module("a", cartan_register_media=lambda register: register("same", object))
    b = _module("b", cartan_register_media=lambda register: register("same", int))
    with pytest.raises(plugins.RegistryError, match="registered twice.*'a'.*'b'|registered twice.*'b'.*'a'"):
        plugins.reset_registry([("a", a), ("b", b)])


def test_duplicate_of_builtin_group_is_an_error():
    clash = _module("clash", cartan_register_groups=lambda register: register("SO3", object))
    with pytest.raises(plugins.RegistryError, match="'SO3' is registered twice"):
        plugins.reset_registry([("clash", clash)])


def test_names_must_be_kebab_case():
    bad = _module("bad", cartan_register_media=lambda register: register("Bad_Name", object))
    with pytest.raises(plugins.RegistryError, match="kebab-case"):
        plugins.reset_registry([("bad", bad)])


def test_plugin_failing_to_import_warns_and_rest_works(monkeypatch):
    real = md.entry_points

    broken = md.EntryPoint(name="broken", value="cartan_does_not_exist.plugin", group="cartan")

    def fake_entry_points(group=None, **kw):
        eps = list(real(group=group, **kw))
        return [*eps, broken]

    monkeypatch.setattr(plugins.md, "entry_points", fake_entry_points)
    with pytest.warns(plugins.PluginWarning, match="'broken'.*cartan_does_not_exist"):
        reg = plugins.reset_registry()
    assert "SO3" in reg.table("groups")


def test_plugin_hook_raising_warns_and_rest_works():
    def explode(register):
        raise RuntimeError("boom")

    mod = _module("exploding", cartan_register_media=explode)
    with pytest.warns(plugins.PluginWarning, match="'exploding'.*boom"):
        reg = plugins.reset_registry([("exploding", mod)])
    assert "SE3" in reg.table("groups")


def test_manager_is_lazy_and_cached():
    plugins._registry = None
    assert plugins._registry is None
    first = plugins.get_registry()
    assert plugins.get_registry() is first


def test_unknown_registry_kind():
    with pytest.raises(plugins.RegistryError, match="unknown registry 'things'"):
        cartan.registry("things")


def test_no_warnings_from_builtin_plugins():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        plugins.reset_registry()


def test_register_cases_skips_cases_whose_optional_dependency_is_missing(tmp_path, monkeypatch):
    """A plugin's cases derive from an optional package: without it the plugin registers no
    case (and works otherwise); a missing cases module is an error."""
    from cartan.plugins import register_cases, register_scenes

    (tmp_path / "cases_without_dep.py").write_text("import no_such_package_for_cases\n")
    (tmp_path / "cases_ok.py").write_text(
        "class C:\n    name = 'c-one'\n\ndef all_cases():\n    return [C()]\n")
    (tmp_path / "scenes").mkdir()
    (tmp_path / "scenes" / "s-one.toml").write_text("")
    monkeypatch.syspath_prepend(str(tmp_path))
    got = {}
    register_cases(got.__setitem__, "cases_without_dep")
    assert got == {}
    register_cases(got.__setitem__, "cases_ok")
    assert list(got) == ["c-one"]
    with pytest.raises(ModuleNotFoundError):
        register_cases(got.__setitem__, "no_such_cases_module")
    register_scenes(got.__setitem__, str(tmp_path / "plugin.py"))
    assert got["s-one"] == tmp_path / "scenes" / "s-one.toml"
