"""The ``cartan converge`` and ``cartan verify`` commands.

``cartan converge CASE -i lie-verlet -i rkmk4 -s lattice -s collocation --levels 5 -o wp.nc``
    refine one registered verification case (:func:`cartan.study.converge`) and write the
    Dataset (error, cost, observed order per integrator × scheme) to netCDF; ``--refine``
    chooses space, time or both; ``--scheduler local|tcp://host:port`` runs the tasks on dask,
    ``--store DIR`` keeps every finished task so that a rerun continues where it stopped;
``cartan verify [--medium NAME] [--case NAME] [--quick] [--out docs/verification]``
    runs every registered case (or the selected ones) and writes a report: ``README.md`` (one
    row per case × integrator × scheme: error, observed against expected order, pass/fail,
    tolerance and its reason), the charts (error against dx or Δt, work-precision) and
    ``verification.nc`` with every number.  Exit status 1 when a check fails.

Bad input prints one line ``cartan: error: ...`` on stderr and exits with status 2.
:func:`register` adds the commands to a click group.
"""

from __future__ import annotations

import math
import pathlib
import re
from typing import Any

import click

from .cli_run import RUN_ERROR, CommandError, _OneLineCommand

__all__ = ["converge_cmd", "register", "verify_cmd"]



def _cases() -> dict[str, Any]:
    """Registered verification cases by name."""
    from .plugins import get_registry

    return {name: e.obj for name, e in get_registry().table("cases").items()}


def _case(name: str) -> Any:
    from .plugins import RegistryError

    try:
        cases = _cases()
    except RegistryError as exc:
        raise CommandError(str(exc)) from None
    if name not in cases:
        known = ", ".join(sorted(cases)) or "none registered"
        raise CommandError(f"unknown case {name!r} (known: {known})")
    obj = cases[name]
    return obj() if isinstance(obj, type) else obj


def _study(case: Any, integrators, schemes, levels, refine, scheduler, store):
    from .plugins import RegistryError
    from .simulate import InstabilityError
    from .study import StudyError, converge

    try:
        return converge(case, integrators=list(integrators) or None, schemes=list(schemes) or None, levels=levels,
                        refine=refine, client=scheduler, store=store)
    except (StudyError, RegistryError, ValueError, TypeError, KeyError) as exc:
        raise CommandError(" ".join(str(exc).split()) or type(exc).__name__) from None
    except InstabilityError as exc:
        raise CommandError(str(exc), RUN_ERROR) from None


_scheduler_option = click.option(
    "--scheduler", metavar="ADDRESS",
    help="Run the tasks on dask: 'local' (a 2-worker LocalCluster) or tcp://host:port (a running scheduler).")
_store_option = click.option(
    "--store", type=click.Path(file_okay=False, path_type=pathlib.Path),
    help="Directory keeping one file per finished task; a rerun skips them.")


@click.command("converge", cls=_OneLineCommand)
@click.argument("case_name", metavar="CASE")
@click.option("-i", "--integrator", "integrators", multiple=True, help="Integrator (repeatable; default: the case's).")
@click.option("-s", "--scheme", "schemes", multiple=True, help="Scheme (repeatable; default: lattice).")
@click.option("--levels", type=int, default=None, help="Refinement levels (default: the case's, at least 2).")
@click.option("--refine", type=click.Choice(["space", "time", "both"]), default=None,
              help="What to refine (default: space if the case is refined in space, else time).")
@click.option("-o", "--output", type=click.Path(dir_okay=False, path_type=pathlib.Path), default=None,
              help="netCDF file to write (default: CASE-converge.nc).")
@click.option("--plot", "plot_prefix", type=click.Path(dir_okay=False, path_type=pathlib.Path), default=None,
              help="Also write PREFIX-error.png and PREFIX-work-precision.png.")
@_scheduler_option
@_store_option
def converge_cmd(case_name, integrators, schemes, levels, refine, output, plot_prefix, scheduler, store) -> None:
    """Convergence and work-precision study of one registered verification case."""
    from . import io, study

    case = _case(case_name)
    levels = int(levels if levels is not None else getattr(case, "levels", 4) or 4)
    if levels < 2:
        raise CommandError(f"--levels must be ≥ 2, got {levels}")
    ds = _study(case, integrators, schemes, levels, refine, scheduler, store)
    output = output or pathlib.Path(f"{case_name}-converge.nc")
    try:
        io.write_dataset(ds, output)
        if plot_prefix is not None:
            study.plot_error_vs_h(ds, f"{plot_prefix}-error.png")
            study.plot_work_precision(ds, f"{plot_prefix}-work-precision.png")
    except OSError as exc:
        raise CommandError(f"{exc.filename or output}: {exc.strerror or exc}", RUN_ERROR) from None
    for integ in ds["integrator"].values:
        for sch in ds["scheme"].values:
            sel = ds.sel(integrator=integ, scheme=sch)
            click.echo(f"{case_name}  {integ} / {sch}: error {float(sel['error'][-1]):.3g}, observed order "
                       f"{float(sel['observed_order']):.2f} (expected {float(sel['expected_order']):.2f})")
    click.echo(f"wrote {output}")


def _fmt(x: float, spec: str = ".3g") -> str:
    return "—" if not math.isfinite(x) else format(x, spec)


def _cell(text: Any) -> str:
    return " ".join(str(text).split()).replace("|", "\\|")


def _prefixed(ds: Any, name: str) -> Any:
    """The case's Dataset with every variable and dimension prefixed ``name__``."""
    rename = {v: f"{name}__{v}" for v in [*ds.variables]}
    out = ds.rename(rename)
    for v in out.variables:
        out[v].attrs.setdefault("case", name)
    return out


@click.command("verify", cls=_OneLineCommand)
@click.option("--medium", "media", multiple=True, help="Only the cases of this medium (repeatable).")
@click.option("--case", "case_names", multiple=True, help="Only this case (repeatable).")
@click.option("-s", "--scheme", "schemes", multiple=True, help="Scheme (repeatable; default: lattice).")
@click.option("--quick", is_flag=True, help="The case's own levels (the full run adds one finer level).")
@click.option("--out", "out_dir", type=click.Path(file_okay=False, path_type=pathlib.Path),
              default=pathlib.Path("docs/verification"), show_default=True, help="Report directory.")
@_scheduler_option
@_store_option
def verify_cmd(media, case_names, schemes, quick, out_dir, scheduler, store) -> None:
    """Run the registered verification cases and write a report (Markdown, charts, netCDF)."""
    import xarray as xr

    from . import __version__, io, study
    from .plugins import RegistryError

    try:
        table = _cases()
    except RegistryError as exc:
        raise CommandError(str(exc)) from None
    unknown = [c for c in case_names if c not in table]
    if unknown:
        raise CommandError(f"unknown case {unknown[0]!r} (known: {', '.join(sorted(table)) or 'none registered'})")
    selected = {}
    for name in sorted(table):
        obj = table[name]
        case = obj() if isinstance(obj, type) else obj
        if case_names and name not in case_names:
            continue
        if media and getattr(case, "medium", None) not in media:
            continue
        selected[name] = case
    if not selected:
        raise CommandError("no registered case matches the selection" if table else "no verification case registered")
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise CommandError(f"{out_dir}: {exc.strerror or exc}") from None

    rows, parts, failed, total = [], [], 0, 0
    for name, case in selected.items():
        own = getattr(case, "levels", 4)
        own = len(own) if isinstance(own, tuple | list) else int(own or 4)
        # tolerances are stated at a case's finest own level: --quick runs exactly those levels,
        # the full run adds one finer level
        levels = own if quick else own + 1
        ds = _study(case, [], schemes, levels, None, scheduler,
                    None if store is None else store / re.sub(r"[^A-Za-z0-9_.-]", "_", name))
        safe = re.sub(r"[^A-Za-z0-9_.-]", "_", name)
        charts = [study.plot_error_vs_h(ds, out_dir / f"{safe}-error.png"),
                  study.plot_work_precision(ds, out_dir / f"{safe}-work-precision.png")]
        parts.append(_prefixed(ds, name))
        for integ in ds["integrator"].values:
            for sch in ds["scheme"].values:
                sel = ds.sel(integrator=integ, scheme=sch)
                ok = bool(sel["passed"])
                total += 1
                failed += not ok
                rows.append("| " + " | ".join(_cell(c) for c in (
                    name, getattr(case, "medium", ""), getattr(case, "reference", ""), f"{integ} / {sch}",
                    ds.attrs["refine"], _fmt(float(sel["error"][-1])),
                    f"{_fmt(float(sel['observed_order']), '.2f')} vs {_fmt(float(sel['expected_order']), 'g')}",
                    "pass" if ok else "**FAIL**",
                    f"{_fmt(ds.attrs['tolerance'])}: {ds.attrs['tolerance_reason']}",
                    f"[error]({charts[0].name}), [work]({charts[1].name})")) + " |")
    merged = xr.merge(parts, compat="override", combine_attrs="drop")
    merged.attrs = {"Conventions": "CF-1.11", "title": "cartan verification report", "source": f"cartan {__version__}",
                    "history": io.history_line("cartan verify" + (" --quick" if quick else "")),
                    "cases": ", ".join(selected)}
    io.write_dataset(merged, out_dir / "verification.nc")
    header = ("| case | medium | reference | integrator / scheme | refined | error | observed vs expected order "
              "| result | tolerance: reason | charts |\n|---|---|---|---|---|---|---|---|---|---|")
    text = (f"# Verification report\n\nWritten by `cartan verify{' --quick' if quick else ''}` (cartan {__version__}): "
            f"{total - failed} of {total} checks pass.  The error is the finest level's; the observed order is "
            "the fitted slope of log error against log dx (or Δt) on the asymptotic levels.  Every number is in "
            "`verification.nc`.\n\n" + header + "\n" + "\n".join(rows) + "\n")
    (out_dir / "README.md").write_text(text)
    click.echo(f"{total - failed} of {total} checks pass; wrote {out_dir / 'README.md'}")
    if failed:
        raise CommandError(f"{failed} of {total} verification checks failed (see {out_dir / 'README.md'})", RUN_ERROR)


def register(main: click.Group) -> None:
    """Add the ``converge`` and ``verify`` commands to the click group ``main``."""
    main.add_command(converge_cmd)
    main.add_command(verify_cmd)
