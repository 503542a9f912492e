"""The ``cartan run`` and ``cartan plot`` commands.

``cartan run scene.toml -o out.nc``
    run a scene file (or ``--scene NAME`` for a registered scene; ``--restart out.nc`` to
    continue a run from its last checkpoint), overriding its ``[run]`` settings with
    ``--integrator``, ``--scheme``, ``--dt``, ``--t-end``, ``--save-every`` and
    ``--checkpoint-every``.  Scenes with ``mode = "static"`` or ``mode = "continuation"``
    are solved by :func:`cartan.statics.solve_static` or followed by
    :func:`cartan.continuation.continuation` with their ``[static]`` / ``[continuation]``
    settings (the dynamic options do not apply to them);
``cartan plot out.nc [-o out.png]``
    dynamic runs: configuration snapshots coloured by time and the energies against time;
    static results: the equilibrium shape, its displacement and the Newton residuals;
    continuation results: the load–displacement chart and shapes along the path.

Bad input — malformed TOML, unknown names, bad parameters or options — prints one line
``cartan: error: ...`` on stderr and exits with status 2 without writing anything; a run
that blows up prints the :class:`~cartan.simulate.InstabilityError` message (which names the
file holding the last good state), and a static or continuation run that finds no
equilibrium the :class:`~cartan.statics.ConvergenceError` message; both exit with status 1.
:func:`register` adds the commands to a click group.
"""

from __future__ import annotations

import pathlib
import shlex
import warnings
from typing import Any

import click

__all__ = ["plot_cmd", "register", "run_cmd"]

USAGE_ERROR = 2
RUN_ERROR = 1


class CommandError(click.ClickException):
    """A one-line ``cartan: error: ...`` on stderr and an exit status."""

    def __init__(self, message: str, exit_code: int = USAGE_ERROR):
        super().__init__(" ".join(str(message).split()))
        self.exit_code = exit_code

    def show(self, file: Any = None) -> None:
        click.echo(f"cartan: error: {self.format_message()}", err=True)


class _OneLineCommand(click.Command):
    """A click command whose option errors are one line too, and which keeps its raw arguments."""

    def make_context(self, info_name, args, parent=None, **extra):
        raw = list(args)
        try:
            ctx = super().make_context(info_name, args, parent=parent, **extra)
        except click.UsageError as exc:
            raise CommandError(exc.format_message()) from None
        ctx.meta["cartan.raw_args"] = raw
        return ctx


def _command_line(ctx: click.Context) -> str:
    return shlex.join(["cartan", ctx.info_name or "run", *ctx.meta.get("cartan.raw_args", [])])


def _show_warning(message, category, filename, lineno, file=None, line=None) -> None:
    click.echo(f"cartan: warning: {' '.join(str(message).split())}", err=True)


@click.command("run", cls=_OneLineCommand)
@click.argument("scene_file", required=False, type=click.Path(dir_okay=False, path_type=pathlib.Path))
@click.option(
    "--scene", "scene_name", metavar="NAME", help="Run the registered scene NAME (see `cartan list scenes`)."
)
@click.option(
    "-o",
    "--output",
    type=click.Path(dir_okay=False, path_type=pathlib.Path),
    help="netCDF file to write (default: NAME.nc, or the --restart file).",
)
@click.option("--integrator", help="Registered integrator (overrides the scene's [run] integrator).")
@click.option("--scheme", help="Registered scheme (overrides the scene's [run] scheme).")
@click.option("--dt", type=float, help="Time step.")
@click.option("--t-end", "t_end", type=float, help="Final time.")
@click.option("--save-every", type=int, help="Steps between saved frames.")
@click.option(
    "--restart",
    type=click.Path(dir_okay=False, path_type=pathlib.Path),
    help="Continue the run in this file from its last checkpoint.",
)
@click.option("--checkpoint-every", type=int, help="Write a checkpoint every this many saves.")
@click.option("--progress/--no-progress", default=None, help="Progress bar (default: only on a terminal).")
@click.pass_context
def run_cmd(
    ctx: click.Context,
    scene_file,
    scene_name,
    output,
    integrator,
    scheme,
    dt,
    t_end,
    save_every,
    restart,
    checkpoint_every,
    progress,
) -> None:
    """Run a scene file, a registered scene (--scene NAME), or continue a run (--restart)."""
    from .plugins import RegistryError
    from .scene import SceneError, load_scene, scene
    from .simulate import InstabilityError, simulate
    from .statics import ConvergenceError

    if scene_file is not None and scene_name is not None:
        raise CommandError("give a scene file or --scene NAME, not both")
    for name, value in (("--dt", dt), ("--t-end", t_end)):
        if value is not None and not value > 0:
            raise CommandError(f"{name} must be > 0, got {value:g}")
    for name, value in (("--save-every", save_every), ("--checkpoint-every", checkpoint_every)):
        if value is not None and value < 1:
            raise CommandError(f"{name} must be ≥ 1, got {value}")
    try:
        if scene_file is not None:
            sc = load_scene(scene_file)
        elif scene_name is not None:
            sc = scene(scene_name)
        elif restart is not None:
            sc = None
        else:
            raise CommandError("give a scene file, --scene NAME, or --restart FILE")
        if output is None:
            output = restart if restart is not None else pathlib.Path(f"{sc.name or 'run'}.nc")
        if sc is not None and sc.mode != "dynamic":
            dynamic_only = {
                "--integrator": integrator,
                "--dt": dt,
                "--t-end": t_end,
                "--save-every": save_every,
                "--restart": restart,
                "--checkpoint-every": checkpoint_every,
            }
            given = [name for name, value in dynamic_only.items() if value is not None]
            if given:
                raise CommandError(
                    f"{', '.join(given)}: only for dynamic scenes; scene {sc.name!r} has mode = {sc.mode!r} "
                    f"(its settings are in the [{sc.mode}] table)"
                )
            if scheme is not None and scheme != "lattice":
                raise CommandError(f"--scheme: {sc.mode} runs use the 'lattice' scheme only, got {scheme!r}")
            ds = sc.run(output=output, command=_command_line(ctx))
            click.echo(f"wrote {output} ({_summary(ds, sc.mode)})")
            return
        with warnings.catch_warnings():
            warnings.showwarning = _show_warning
            ds = simulate(
                sc,
                integrator=integrator,
                scheme=scheme,
                dt=dt,
                t_end=t_end,
                save_every=save_every,
                output=output,
                restart=restart,
                checkpoint_every=checkpoint_every,
                progress=progress,
                command=_command_line(ctx),
            )
    except CommandError:
        raise
    except (InstabilityError, ConvergenceError) as exc:
        raise CommandError(str(exc), RUN_ERROR) from None
    except (SceneError, RegistryError, ValueError, TypeError) as exc:
        raise CommandError(str(exc)) from None
    except OSError as exc:
        raise CommandError(f"{exc.filename or output}: {exc.strerror or exc}", RUN_ERROR) from None
    t = ds["time"].values
    click.echo(f"wrote {output} ({len(t)} frames, t = {t[0]:g} to {t[-1]:g})")


def _summary(ds: Any, mode: str) -> str:
    """One line about a static or continuation result."""
    if mode == "static":
        text = f"static equilibrium, {ds.attrs['newton_iterations']} Newton iterations"
        if "measure" in ds.attrs:
            text += f"; {ds.attrs['measure']} = {ds.attrs['measured_displacement']:.6g}"
        return text
    lam = ds["load_factor"].values
    text = f"continuation, {ds.sizes['path']} path points, λ = {lam[0]:g} to {lam[-1]:g}"
    crit = [f"{kind} at λ = {load:.6g}" for kind, load in zip(ds["critical_kind"].values,
                                                              ds["critical_load"].values, strict=True)]
    return text + (f"; {', '.join(crit)}" if crit else "; no critical point")


@click.command("plot", cls=_OneLineCommand)
@click.argument("run_file", type=click.Path(dir_okay=False, path_type=pathlib.Path))
@click.option(
    "-o",
    "--output",
    type=click.Path(dir_okay=False, path_type=pathlib.Path),
    help="Image to write (default: RUN_FILE with suffix .png).",
)
@click.option("--snapshots", type=int, default=8, show_default=True, help="Configurations drawn.")
def plot_cmd(run_file: pathlib.Path, output: pathlib.Path | None, snapshots: int) -> None:
    """Plot a run file: snapshots and energies (dynamic), the equilibrium (static) or the
    load–displacement chart (continuation)."""
    from .io import open_dataset
    from .plotting import plot_run, result_kind

    if not run_file.is_file():
        raise CommandError(f"{run_file}: no such file")
    if snapshots < 1:
        raise CommandError(f"--snapshots must be ≥ 1, got {snapshots}")
    try:
        ds = open_dataset(run_file)
    except (OSError, ValueError) as exc:
        raise CommandError(f"{run_file}: not a readable netCDF file ({' '.join(str(exc).split())})") from None
    if result_kind(ds) != "continuation":
        missing = [v for v in ("kinetic_energy", "potential_energy") if v not in ds]
        if missing or "time" not in ds.dims:
            raise CommandError(f"{run_file}: not a cartan run file (missing {', '.join(missing) or 'time'})")
    output = output if output is not None else run_file.with_suffix(".png")
    try:
        plot_run(ds, output, snapshots=snapshots)
    except (OSError, ValueError) as exc:
        raise CommandError(f"{output}: {' '.join(str(exc).split())}", RUN_ERROR) from None
    click.echo(f"wrote {output}")


def register(main: click.Group) -> None:
    """Add the ``run`` and ``plot`` commands to the click group ``main``."""
    main.add_command(run_cmd)
    main.add_command(plot_cmd)
