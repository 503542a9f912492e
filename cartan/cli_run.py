"""The ``cartan run`` and ``cartan plot`` commands.

``cartan run scene.toml -o out.nc``
    run a scene file (or ``--scene NAME`` for a registered scene; ``--restart out.nc`` to
    continue a run from its last checkpoint), overriding its ``[run]`` settings with
    ``--integrator``, ``--scheme``, ``--dt``, ``--t-end``, ``--save-every`` and
    ``--checkpoint-every``.  Scenes with ``mode = "static"`` or ``mode = "continuation"``
    are solved by :func:`cartan.statics.solve_static` or followed by
    :func:`cartan.continuation.continuation` with their ``[static]`` / ``[continuation]``
    settings (the dynamic options do not apply to them); scenes with a ``[flow]`` table run
    the flow a plugin registered under its ``kind`` (registry ``"flows"``);
``cartan plot out.nc [-o out.png]``
    dynamic runs: configuration snapshots coloured by time and the energies against time;
    static results: the equilibrium shape, its displacement and the Newton residuals;
    continuation results: the load–displacement chart and shapes along the path; surfaces and
    solids (d = 3) in 3D coloured by ``--field``, a solid's slice with ``--slice AXIS[=INDEX]``;
    a medium that draws its own picture (:meth:`cartan.medium.Medium.draw`) draws it, unless
    ``--generic``.

Bad input — malformed TOML, unknown names, bad parameters or options, a run too long or too
large for the limits (``--max-steps``, ``CARTAN_MAX_STEPS``, ``CARTAN_MAX_MEMORY``), an output
that cannot be written — prints one line ``cartan: error: ...`` on stderr and exits with
status 2 without writing anything; every setting is checked before the run starts.  A run
that blows up prints the :class:`~cartan.simulate.InstabilityError` message (which names the
file holding the last good state, ``NAME.lastgood.nc`` beside the output), and a static or
continuation run that finds no equilibrium the :class:`~cartan.statics.ConvergenceError`
message; both exit with status 1.  Without ``-o`` the output is ``NAME.nc`` in the scene
file's folder (the current folder for ``--scene``), NAME being the scene's name reduced to a
plain file name (:func:`default_output`).  SIGTERM and SIGHUP stop a run like Ctrl-C, so that
no temporary file is left behind.  :func:`register` adds the commands to a click group.
"""

from __future__ import annotations

import contextlib
import os
import pathlib
import re
import shlex
import signal
import warnings
from collections.abc import Iterator
from typing import Any

import click

__all__ = ["default_output", "plot_cmd", "register", "run_cmd", "safe_name"]

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


@contextlib.contextmanager
def _warnings_as_lines() -> Iterator[None]:
    """Warnings as one line ``cartan: warning: ...`` each; numpy's floating-point
    RuntimeWarnings are left out (the blow-up tests and the checks of the settings report
    what they are about)."""
    with warnings.catch_warnings():
        warnings.showwarning = _show_warning
        warnings.simplefilter("ignore", RuntimeWarning)
        yield


@contextlib.contextmanager
def _stop_cleanly() -> Iterator[None]:
    """SIGTERM and SIGHUP raise SystemExit (status 128 + signal) while a command runs, so that
    a write in progress removes its temporary file as on Ctrl-C.  Signals that are not at their
    default (ignored under ``nohup``, or handled by the caller) are left as they are."""

    def stop(signum: int, _frame: Any) -> None:
        raise SystemExit(128 + signum)

    previous = {}
    for name in ("SIGTERM", "SIGHUP"):
        sig = getattr(signal, name, None)
        if sig is None or signal.getsignal(sig) is not signal.SIG_DFL:
            continue
        try:
            previous[sig] = signal.signal(sig, stop)
        except (ValueError, OSError):  # not the main thread: keep the default
            pass
    try:
        yield
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)


def safe_name(name: str) -> str:
    """A plain file name from a scene's ``name``.

    Characters other than letters, digits, ``.``, ``-`` and ``_`` become ``_`` (so no path
    separator survives), leading dots are dropped (no ``..``, no hidden file), the result is
    at most 200 bytes long, and an empty result is ``"run"``.

    Parameters
    ----------
    name : str

    Returns
    -------
    str
    """
    text = re.sub(r"[^\w.-]+", "_", name).lstrip(".")
    while len(text.encode("utf-8")) > 200:
        text = text[:-1]
    return text or "run"


def default_output(scene_name: str, scene_file: pathlib.Path | None) -> pathlib.Path:
    """The output of ``cartan run`` without ``-o``: ``NAME.nc`` (NAME from :func:`safe_name`) in
    the folder of the scene file, or in the current folder for a registered scene.

    Parameters
    ----------
    scene_name : str
    scene_file : pathlib.Path or None

    Returns
    -------
    pathlib.Path
    """
    name = f"{safe_name(scene_name)}.nc"
    return scene_file.parent / name if scene_file is not None else pathlib.Path(name)


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
@click.option(
    "--max-steps",
    type=int,
    help="Most time steps the run may take (default: $CARTAN_MAX_STEPS, else 1000000000).",
)
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
    max_steps,
    progress,
) -> None:
    """Run a scene file, a registered scene (--scene NAME), or continue a run (--restart)."""
    with _stop_cleanly(), _warnings_as_lines():
        _run(ctx, scene_file, scene_name, output, integrator, scheme, dt, t_end, save_every, restart,
             checkpoint_every, max_steps, progress)


def _run(
    ctx: click.Context,
    scene_file: pathlib.Path | None,
    scene_name: str | None,
    output: pathlib.Path | None,
    integrator: str | None,
    scheme: str | None,
    dt: float | None,
    t_end: float | None,
    save_every: int | None,
    restart: pathlib.Path | None,
    checkpoint_every: int | None,
    max_steps: int | None,
    progress: bool | None,
) -> None:
    """``cartan run``: the settings are checked by the library (:func:`cartan.load_scene`,
    :func:`cartan.simulate`, :meth:`cartan.scene.Scene.run`), whose errors become one line."""
    from .plugins import RegistryError
    from .scene import SceneError, load_scene, scene
    from .simulate import InstabilityError, simulate
    from .statics import ConvergenceError

    if scene_file is not None and scene_name is not None:
        raise CommandError("give a scene file or --scene NAME, not both")
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
            output = restart if restart is not None else default_output(sc.name or scene_name or "run", scene_file)
        if scene_file is not None and _same_file(output, scene_file):
            raise CommandError(f"-o {output}: that is the scene file; give another output file")
        if sc is not None and sc.mode != "dynamic":
            dynamic_only = {
                "--integrator": integrator,
                "--dt": dt,
                "--t-end": t_end,
                "--save-every": save_every,
                "--restart": restart,
                "--checkpoint-every": checkpoint_every,
                "--max-steps": max_steps,
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
            max_steps=max_steps,
        )
    except CommandError:
        raise
    except (InstabilityError, ConvergenceError) as exc:
        raise CommandError(str(exc), RUN_ERROR) from None
    except (SceneError, RegistryError, ValueError, TypeError, ArithmeticError) as exc:
        raise CommandError(str(exc) or type(exc).__name__) from None
    except MemoryError:
        raise CommandError(
            "not enough memory for this run; use fewer nodes or frames (the memory limit is set by "
            "the environment variable CARTAN_MAX_MEMORY)"
        ) from None
    except OSError as exc:
        raise CommandError(f"{exc.filename or output}: {exc.strerror or exc}", RUN_ERROR) from None
    t = ds["time"].values
    click.echo(f"wrote {output} ({len(t)} frames, t = {t[0]:g} to {t[-1]:g})")


def _same_file(a: pathlib.Path, b: pathlib.Path) -> bool:
    try:
        return os.path.samefile(a, b)
    except OSError:
        return False


def _summary(ds: Any, mode: str) -> str:
    """One line about a static, flow or continuation result."""
    if mode == "static":
        text = f"static equilibrium, {ds.attrs['newton_iterations']} Newton iterations"
        if "measure" in ds.attrs:
            text += f"; {ds.attrs['measure']} = {ds.attrs['measured_displacement']:.6g}"
        return text
    if mode == "flow":
        text = f"{ds.attrs.get('flow', 'flow')} flow, {ds.sizes.get('step', 1) - 1} steps"
        if "flow_time" in ds:
            text += f", t = {float(ds['flow_time'].values[-1]):.6g}"
        energy = next((n for n in ("bending_energy", "energy") if n in ds and ds[n].dims == ("step",)), None)
        if energy is not None:
            e = ds[energy].values
            text += f", {energy} {e[0]:.6g} to {e[-1]:.6g}"
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
@click.option("--field", default=None,
              help="A surface (d = 2 in space) or a solid (d = 3) is drawn in 3D coloured by this node variable "
                   "(default: the displacement's norm); a variable with dimensions beyond the nodes takes "
                   "its component as NAME[a,b] (labels or indices, e.g. nominal_force_stress[x,u]).")
@click.option("--slice", "slice_", metavar="AXIS[=INDEX]", default=None,
              help="For a solid (d = 3), also draw the material slice AXIS = u, v or w through the middle node "
                   "(or node INDEX), deformed and coloured by --field.")
@click.option("--generic", is_flag=True, default=False,
              help="Draw the generic picture even when the medium draws its own (--field and --slice imply it).")
def plot_cmd(run_file: pathlib.Path, output: pathlib.Path | None, snapshots: int, field: str | None,
             slice_: str | None, generic: bool) -> None:
    """Plot a run file: the medium's own picture when it has one, else snapshots and energies
    (dynamic), the equilibrium (static) or the load–displacement chart (continuation)."""
    from .io import open_dataset
    from .plotting import plot_run, result_kind

    if not run_file.is_file():
        raise CommandError(f"{run_file}: no such file")
    if snapshots < 1:
        raise CommandError(f"--snapshots must be ≥ 1, got {snapshots}")
    try:
        ds = open_dataset(run_file)
    except ValueError as exc:  # names the file
        raise CommandError(str(exc)) from None
    except OSError as exc:
        raise CommandError(f"{run_file}: not a readable netCDF file ({' '.join(str(exc).split())})") from None
    if result_kind(ds) != "continuation":
        missing = [v for v in ("kinetic_energy", "potential_energy") if v not in ds]
        if missing or "time" not in ds.dims:
            raise CommandError(f"{run_file}: not a cartan run file (missing {', '.join(missing) or 'time'})")
    output = output if output is not None else run_file.with_suffix(".png")
    try:
        plot_run(ds, output, snapshots=snapshots, field=field, slice=slice_, generic=generic)
    except ValueError as exc:  # a --field or --slice the result does not have: names the option's value
        raise CommandError(f"{run_file}: {' '.join(str(exc).split())}") from None
    except OSError as exc:
        raise CommandError(f"{output}: {' '.join(str(exc).split())}", RUN_ERROR) from None
    click.echo(f"wrote {output}")


def register(main: click.Group) -> None:
    """Add the ``run`` and ``plot`` commands to the click group ``main``."""
    main.add_command(run_cmd)
    main.add_command(plot_cmd)
