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
    ``verification.nc`` with every number.  Static cases (equilibria; "integrator" ``newton``)
    are refined in space like the others.  When a case with ``compare_methods = True`` (the rod's
    ring flexural wave) is selected it also compares every integrator × scheme on it (:data:`METHOD_INTEGRATORS` ×
    :data:`METHOD_SCHEMES`): work-precision, error against dx, the invariants (integrability
    residual, energy error) against time and the integrability residual level by level.  A case of
    ``kind = "stability"`` contributes its own section (``Case.report_section``; the stiff rod's
    stability map, explicit against implicit).  Exit status 1 when a check fails.

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



#: What ``cartan verify`` compares on the case with ``compare_methods = True`` (the rod's ring
#: flexural wave, whose motion mixes non-commuting translations and rotations, so that the
#: integrability of the stored strains is a real constraint).
METHOD_INTEGRATORS = ("lie-verlet", "rkmk4", "lie-euler", "forward-euler")
METHOD_SCHEMES = ("lattice", "collocation")
#: The method of the paper (collocation in space, Lie–Euler in time).
PAPER_METHOD = ("lie-euler", "collocation")


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
@click.option("-s", "--scheme", "schemes", multiple=True,
              help="Scheme (repeatable; default: the case's default schemes, else lattice).")
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
@click.option("-s", "--scheme", "schemes", multiple=True,
              help="Scheme (repeatable; default: the case's default schemes, else lattice).")
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

    rows, parts, sections, failed, total = [], [], [], 0, 0
    for name, case in selected.items():
        if getattr(case, "kind", "convergence") == "stability":
            text, dss, checks, bad = case.report_section(out_dir, quick, scheduler)
            sections.append(text)
            parts.extend(_prefixed(d, name) if i == 0 else _prefixed(d, f"{name}-{i}") for i, d in enumerate(dss))
            total += checks
            failed += bad
            continue
        own = getattr(case, "levels", 4)
        own = list(own) if isinstance(own, tuple | list) else list(range(int(own or 4)))
        # tolerances are stated at a case's finest own level: --quick runs exactly those levels
        # (which need not start at 0), the full run adds one finer level
        levels = own if quick else [*own, own[-1] + 1]
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
                    f"{_fmt(float(sel['tolerance']))}: {ds.attrs['tolerance_reason']}",
                    f"[error]({charts[0].name}), [work]({charts[1].name})")) + " |")
    method_text = ""
    method_case = next((c for c in selected.values() if getattr(c, "compare_methods", False)), None)
    if method_case is not None:
        method_text, mparts, mtotal, mfailed = _method_study(method_case, quick, out_dir, scheduler, store)
        parts.extend(mparts)
        total += mtotal
        failed += mfailed
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
            "`verification.nc`.\n\n" + header + "\n" + "\n".join(rows) + "\n" + method_text + "".join(sections))
    (out_dir / "README.md").write_text(text)
    click.echo(f"{total - failed} of {total} checks pass; wrote {out_dir / 'README.md'}")
    if failed:
        raise CommandError(f"{failed} of {total} verification checks failed (see {out_dir / 'README.md'})", RUN_ERROR)


def _method_study(case: Any, quick: bool, out_dir: pathlib.Path, scheduler: Any, store: Any):
    """Every integrator × scheme of :data:`METHOD_INTEGRATORS` × :data:`METHOD_SCHEMES` on ``case``,
    refined in space: (Markdown section, Datasets for the netCDF, checks, failed checks)."""
    import numpy as np

    from . import study

    name = case.name
    own = getattr(case, "levels", 4)
    own = len(own) if isinstance(own, tuple | list) else int(own or 4)
    levels = own if quick else own + 1
    ds = _study(case, METHOD_INTEGRATORS, METHOD_SCHEMES, levels, "space", scheduler,
                None if store is None else store / f"{name}-methods")
    ds["error"] = ds["error"].where(np.isfinite(ds["error"]))  # a blown-up run has no error: NaN
    middle = (levels - 1) // 2
    tr = study.traces(case, METHOD_INTEGRATORS, METHOD_SCHEMES, middle)
    wp = study.plot_work_precision(ds, out_dir / f"{name}-methods-work-precision.png")
    ev = study.plot_error_vs_h(ds, out_dir / f"{name}-methods-error.png")
    inv = study.plot_traces(tr, out_dir / f"{name}-methods-invariants.png")
    judged = {str(k).split("/")[0] for k in (getattr(case, "tolerances", {}) or {})}
    judged |= set(getattr(case, "default_integrators", ()))

    def short(status: str) -> str:
        m = re.search(r"unstable at step \d+ \(t = [^)]*\)", status)
        return m.group(0) if m else status

    rows, total, failed = [], 0, 0
    for integ in ds["integrator"].values:
        for sch in ds["scheme"].values:
            sel = ds.sel(integrator=integ, scheme=sch)
            statuses = [str(v) for v in np.ravel(sel["status"].values) if str(v) != "ok"]
            if integ in judged:
                ok = bool(sel["passed"])
                total += 1
                failed += not ok
                result = "pass" if ok else "**FAIL**"
                tol = _fmt(float(sel["tolerance"]))
            else:
                result, tol = "—", "—"
            trace_status = str(tr["status"].sel(integrator=integ, scheme=sch).values)
            resid = float(tr["integrability_residual"].sel(integrator=integ, scheme=sch).max(skipna=True))
            energy = float(tr["energy_error"].sel(integrator=integ, scheme=sch).max(skipna=True))
            levels_ok = sum(s == "ok" for s in np.ravel(sel["status"].values))
            status = "ok" if not statuses else f"{levels_ok} of {levels} levels ran; finest: {short(statuses[-1])}"
            paper = " (the paper's method)" if (str(integ), str(sch)) == PAPER_METHOD else ""
            rows.append("| " + " | ".join(_cell(c) for c in (
                f"{integ} / {sch}{paper}", _fmt(float(sel["error"][-1])),
                _fmt(float(sel["wall_time"].sum()), ".3g"),
                f"{_fmt(float(sel['observed_order']), '.2f')} vs {_fmt(float(sel['expected_order']), 'g')}",
                tol, result,
                _fmt(resid) if trace_status == "ok" else "—", _fmt(energy) if trace_status == "ok" else "—",
                status if trace_status == "ok" else f"{status}; level {middle}: {short(trace_status)}")) + " |")

    # the integrability residual of every run, level by level (max over its saved frames)
    nodes = [int(v) for v in ds["n"].isel(integrator=0, scheme=0).values]
    resid_rows = []
    for integ in ds["integrator"].values:
        for sch in ds["scheme"].values:
            sel = ds.sel(integrator=integ, scheme=sch)
            vals = [float(v) if str(st) == "ok" else math.nan
                    for v, st in zip(sel["integrability_residual"].values, sel["status"].values, strict=True)]
            resid_rows.append("| " + " | ".join([f"{integ} / {sch}", *(_fmt(v) for v in vals)]) + " |")

    def residuals(sch: str, level: int) -> list[float]:
        """Residuals of the judged (geometric, resolved) integrators' runs of ``sch`` at ``level``."""
        sel = ds.sel(scheme=sch).isel(level=level)
        return [float(v) for integ, v, st in zip(sel["integrator"].values, sel["integrability_residual"].values,
                                                 sel["status"].values, strict=True)
                if str(integ) in judged and str(st) == "ok" and math.isfinite(float(v))]

    lattice_max = max((v for k in range(levels) for v in residuals("lattice", k)), default=math.nan)
    colloc = [min(residuals("collocation", k), default=math.nan) for k in range(levels)]
    resid_p = study.observed_order(1.0 / np.asarray(nodes, float), colloc)
    n_mid = nodes[middle]
    summary = (f"Temporal integrability residual (stored strains against those of the stepped frames, max over each "
               f"run, with {' and '.join(sorted(judged))}): `lattice` stays at round-off — at most "
               f"{_fmt(lattice_max)} over every level — while the strains `collocation` stores leave those of its "
               f"frames: {' → '.join(_fmt(v) for v in colloc)} from n = {nodes[0]} to n = {nodes[-1]} "
               f"(observed order {_fmt(resid_p, '.2f')} in dx).  The discrete ∂_u has no product rule, so every "
               "step adds O(Δt·hᵖ) times the velocity gradient; on this standing wave the defect follows the "
               "motion (it is largest at the half period, see the invariants chart).")
    text = (f"\n## Schemes and integrators on one analytic case: `{name}`\n\n"
            f"{getattr(case, 'description', '')}; refined in space over {levels} levels (all levels with the "
            f"finest level's Δt), every integrator × scheme, the paper's own method being "
            f"{PAPER_METHOD[1]} + {PAPER_METHOD[0]}.  Rows without a tolerance (integrators the case does not "
            "expect to be accurate here) are reported, not judged (—); a run that blows up has no error (—) "
            "and its status says where it stopped.  The last two columns are the maxima over one run at level "
            f"{middle} (n = {n_mid}, the case's own Δt).\n\n"
            f"{summary}\n\n"
            f"Charts: [work-precision]({wp.name}), [error vs dx]({ev.name}), "
            f"[integrability residual and energy error vs t]({inv.name}).\n\n"
            "| integrator / scheme | error | wall time (all levels) [s] | observed vs expected order | tolerance "
            "| result | max integrability residual | max relative energy error | status |\n"
            "|---|---|---|---|---|---|---|---|---|\n" + "\n".join(rows) + "\n\n"
            "Integrability residual by level (max over the run's saved frames; — where the run blew up):\n\n"
            "| integrator / scheme | " + " | ".join(f"n = {n}" for n in nodes) + " |\n"
            "|---|" + "---|" * len(nodes) + "\n" + "\n".join(resid_rows) + "\n")
    return text, [_prefixed(ds, f"{name}-methods"), _prefixed(tr, f"{name}-invariants")], total, failed


def register(main: click.Group) -> None:
    """Add the ``converge`` and ``verify`` commands to the click group ``main``."""
    main.add_command(converge_cmd)
    main.add_command(verify_cmd)
