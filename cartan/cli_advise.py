"""The ``cartan advise`` command.

``cartan advise SCENE.toml [--check] [--rtol 1e-3] [--pilot-steps 200] [-o advice.nc] [--json]``
    runs the scene (the static solve, the continuation path, or a pilot of a dynamic scene)
    and prints which reductions it admits, each with the measured indicator, the estimated
    error and speed-up and whether it is recommended (:func:`cartan.advise.advise`);
    ``--check`` runs the full and the reduced model side by side and prints the measured
    difference and time ratio beside the prediction (a dynamic scene: the model difference plus
    the two runs' time-step errors, each listed); ``-o`` writes the table as netCDF;
    ``--json`` prints the report as JSON; ``--scene NAME`` advises a registered scene.

``cartan advise SCENE.toml --tol 1e-4 [--chart wp.png] [--pilot-steps 200] [--json]``
    instead proposes the cheapest (integrator, Δt) of a dynamic scene whose final node
    positions are within ``tol`` of a fine reference run, from a short work-precision sweep
    on the scene (:func:`cartan.advise.advise_method`), with the stability map; ``--chart``
    writes the work-precision chart (PNG).  On a static scene it proposes the coarsest grid n
    whose equilibrium node positions are within ``tol`` (relative to their largest
    displacement), by Richardson extrapolation over the grids n, 2n − 1, 4n − 3
    (:func:`cartan.advise.advise_resolution`), extrapolated beyond them from the observed order
    when none is within ``tol``; ``--chart`` then writes the error against n.  A continuation
    scene gets the same advice at its path's final point.  The error is that of the scene's
    ``measure`` when it declares one (``--quantity measure|positions`` chooses).  On a dynamic
    scene the schemes ``--schemes lattice,collocation`` (the default; ``none`` skips) are also
    compared: the scene's integrator on three grids with Δt refined with h, Richardson's
    estimates at the observed order, the cheaper scheme that reaches ``tol`` recommended.

Bad input prints one line ``cartan: error: ...`` on stderr and exits with status 2 without
writing anything; a solve or pilot that fails exits with status 1.
"""

from __future__ import annotations

import json
import math
import pathlib

import click

from .cli_run import RUN_ERROR, CommandError, _OneLineCommand, _stop_cleanly, _warnings_as_lines

__all__ = ["advise_cmd", "register"]


@click.command("advise", cls=_OneLineCommand)
@click.argument("scene_file", required=False, type=click.Path(dir_okay=False, path_type=pathlib.Path))
@click.option("--scene", "scene_name", metavar="NAME", help="Advise the registered scene NAME.")
@click.option("--check", is_flag=True, help="Also run the full and the reduced models side by side.")
@click.option("--rtol", type=float, default=1e-3, show_default=True,
              help="Relative error accepted for an approximate reduction, in (0, 1].")
@click.option("--pilot-steps", type=int, default=200, show_default=True,
              help="Time steps of the pilot run of a dynamic scene.")
@click.option("-o", "--output", type=click.Path(dir_okay=False, path_type=pathlib.Path), default=None,
              help="Write the table as netCDF.")
@click.option("--json", "as_json", is_flag=True, help="Print the report as JSON.")
@click.option("--tol", type=str, default=None, metavar="X",
              help="Propose the cheapest integrator and time step (dynamic scene) or the coarsest grid (static "
                   "scene) reaching this accuracy (continuation scene: its final point).")
@click.option("--chart", type=click.Path(dir_okay=False, path_type=pathlib.Path), default=None,
              help="With --tol: write the work-precision chart (PNG).")
@click.option("--quantity", type=click.Choice(["auto", "measure", "positions"]), default="auto", show_default=True,
              help="With --tol on a static or continuation scene: the error of the scene's measure (auto: when it "
                   "declares one) or of the node positions.")
@click.option("--schemes", "schemes", type=str, default=None, metavar="A,B",
              help="With --tol on a dynamic scene: the schemes compared (default lattice,collocation; 'none' skips "
                   "the comparison).")
def advise_cmd(scene_file, scene_name, check, rtol, pilot_steps, output, as_json, tol, chart, quantity,
               schemes) -> None:
    """Which reductions a scene admits, with the error and speed-up of each (measured)."""
    from . import io

    if (scene_file is None) == (scene_name is None):
        raise CommandError("give a scene file or --scene NAME (one of them)")
    if scene_file is not None and not scene_file.is_file():
        raise CommandError(f"{scene_file}: no such file")
    if not 0.0 < rtol <= 1.0:
        raise CommandError(f"--rtol must be in (0, 1], got {rtol:g}")
    if pilot_steps < 2:
        raise CommandError(f"--pilot-steps must be ≥ 2, got {pilot_steps}")
    tol_value = None
    if tol is not None:
        try:
            tol_value = float(tol)
        except ValueError:
            raise CommandError(f"--tol must be a number > 0, got {tol!r}") from None
        if not math.isfinite(tol_value) or tol_value <= 0.0:
            raise CommandError(f"--tol must be a finite number > 0, got {tol}")
        if check or output is not None:
            raise CommandError("--tol does not combine with --check or -o")
        if chart is not None:
            if scene_file is not None and chart.resolve() == scene_file.resolve():
                raise CommandError(f"--chart {chart}: that is the scene file; give another output file")
            if not chart.parent.is_dir():
                raise CommandError(f"--chart {chart}: no such directory {chart.parent}")
    elif chart is not None:
        raise CommandError("--chart needs --tol")
    if tol_value is None and (quantity != "auto" or schemes is not None):
        raise CommandError("--quantity and --schemes need --tol")
    scheme_list = None
    if schemes is not None:
        scheme_list = [] if schemes.strip() == "none" else [x.strip() for x in schemes.split(",") if x.strip()]
        if schemes.strip() != "none" and not scheme_list:
            raise CommandError(f"--schemes must be scheme names separated by commas, or 'none', got {schemes!r}")
    if output is not None:
        if scene_file is not None and output.resolve() == scene_file.resolve():
            raise CommandError(f"-o {output}: that is the scene file; give another output file")
        try:
            io.check_output(output)
        except (ValueError, OSError) as exc:
            raise CommandError(str(exc)) from None
    subject = scene_file if scene_file is not None else scene_name
    if tol_value is not None:
        options = dict(tol=tol_value, pilot_steps=pilot_steps, quantity=quantity)
        if scheme_list is not None:
            options["schemes"] = tuple(scheme_list)
        _report(subject, options, as_json, chart, lambda report, path: report.plot(path))
    else:
        _report(subject, dict(check=check, rtol=rtol, pilot_steps=pilot_steps), as_json, output,
                lambda report, path: io.write_dataset(report.to_dataset(), path))


def _report(subject, options: dict, as_json: bool, path: pathlib.Path | None, write) -> None:
    """Run :func:`cartan.advise.advise` on ``subject`` with ``options``, print its report (text or
    JSON) and, with ``path``, write it there with ``write(report, path)`` (the table's netCDF file
    or the ``--tol`` chart); failures are one-line errors."""
    from .advise import advise
    from .plugins import RegistryError
    from .scene import SceneError
    from .simulate import InstabilityError
    from .statics import ConvergenceError

    with _stop_cleanly(), _warnings_as_lines():
        try:
            report = advise(subject, **options)
        except (InstabilityError, ConvergenceError) as exc:
            raise CommandError(str(exc), RUN_ERROR) from None
        except (SceneError, RegistryError, ValueError, TypeError, ArithmeticError) as exc:
            raise CommandError(str(exc) or type(exc).__name__) from None
        if path is not None:
            try:
                write(report, path)
            except OSError as exc:
                raise CommandError(f"{exc.filename or path}: {exc.strerror or exc}", RUN_ERROR) from None
    click.echo(json.dumps(report.to_dict(), indent=1, ensure_ascii=False) if as_json else str(report))
    if path is not None:
        click.echo(f"wrote {path}")


def register(main: click.Group) -> None:
    """Add the ``advise`` command to the click group ``main``."""
    main.add_command(advise_cmd)
