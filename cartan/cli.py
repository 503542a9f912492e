"""The ``cartan`` command line.

``cartan --version``
    the package version and the versions of the plugins that were loaded;
``cartan list [groups|spaces|media|integrators|schemes|cases|scenes|commands]``
    every registry entry with the plugin and distribution it came from;
``cartan run scene.toml -o out.nc`` / ``cartan run --scene NAME``
    run a scene and write a netCDF file;
``cartan plot out.nc``
    centreline snapshots and energies against time, as a PNG;
``cartan warm``
    compile every numba kernel into the on-disk cache (run once after installing).

Plugins add commands through the ``cartan_register_commands`` hook
(``register("name", click_command)``).
"""

from __future__ import annotations

import pathlib
import sys

import click

from .cli_advise import register as _register_advise_commands
from .cli_cache import register as _register_cache_commands
from .cli_run import register as _register_run_commands
from .cli_verify import register as _register_verify_commands
from .plugins import KINDS, RegistryError, get_registry


def _describe(obj: object) -> str:
    if isinstance(obj, pathlib.Path):
        return obj.name
    mod = getattr(obj, "__module__", None) or type(obj).__module__
    qual = getattr(obj, "__qualname__", None) or type(obj).__qualname__
    return f"{mod}:{qual}"


def _summary(obj: object) -> str:
    if isinstance(obj, pathlib.Path):
        from .scene import SceneError, read_scene_file

        try:
            text = str(read_scene_file(obj).get("description", "")).strip()
        except SceneError:  # within the limits and rules of every scene file
            return ""
        return text.split(". ")[0].rstrip(".") + "." if text else ""
    doc = (getattr(obj, "__doc__", None) or "").strip().splitlines()
    return doc[0] if doc else ""


class _CartanGroup(click.Group):
    """Click group that also offers the commands registered by plugins."""

    def _plugin_commands(self) -> dict[str, click.Command]:
        try:
            return {n: e.obj for n, e in get_registry().table("commands").items()}
        except RegistryError as exc:  # a broken plugin must not break the CLI
            click.echo(f"cartan: {exc}", err=True)
            return {}

    def list_commands(self, ctx: click.Context) -> list[str]:
        return sorted(set(super().list_commands(ctx)) | set(self._plugin_commands()))

    def get_command(self, ctx: click.Context, cmd_name: str) -> click.Command | None:
        return super().get_command(ctx, cmd_name) or self._plugin_commands().get(cmd_name)


def _version_message() -> str:
    from . import __version__

    lines = [f"cartan {__version__}"]
    try:
        reg = get_registry()
        dists = sorted({(d, v) for d, v in reg.origin.values() if d != "cartan"})
        lines += [f"  plugin distribution {d} {v}" for d, v in dists]
    except RegistryError as exc:
        lines.append(f"  (plugins: {exc})")
    lines.append(f"  Python {sys.version.split()[0]}")
    return "\n".join(lines)


def _print_version(ctx: click.Context, _param: click.Parameter, value: bool) -> None:
    if value and not ctx.resilient_parsing:
        click.echo(_version_message())
        ctx.exit()


@click.group(cls=_CartanGroup, context_settings={"help_option_names": ["-h", "--help"]})
@click.option("--version", is_flag=True, expose_value=False, is_eager=True, callback=_print_version,
              help="Show the version of cartan and of its plugin distributions, then exit.")
def main() -> None:
    """cartan: geometric continuum mechanics of Cartan media."""


@main.command("list")
@click.argument("kind", required=False, type=click.Choice(sorted(KINDS)))
def list_cmd(kind: str | None) -> None:
    """List registered entries and where each came from (all registries by default)."""
    try:
        reg = get_registry()
    except RegistryError as exc:
        raise click.ClickException(str(exc)) from None
    kinds = [kind] if kind else list(KINDS)
    for k in kinds:
        table = reg.table(k)
        click.secho(f"{k} ({len(table)})", bold=True)
        if not table:
            click.echo("  (none registered yet)")
        width = max((len(n) for n in table), default=0)
        for name in sorted(table):
            e = table[name]
            origin = f"{e.distribution} {e.version}".strip()
            summary = _summary(e.obj)
            click.echo(f"  {name:<{width}}  {_describe(e.obj)}  [{origin}]" + (f"  {summary}" if summary else ""))


_register_run_commands(main)
_register_verify_commands(main)
_register_cache_commands(main)
_register_advise_commands(main)


if __name__ == "__main__":  # pragma: no cover
    main()
