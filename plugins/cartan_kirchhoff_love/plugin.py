"""Hook implementations of the ``kirchhoff-love`` plugin (entry point ``cartan_kirchhoff_love.plugin``)."""

from __future__ import annotations

import cartan
from cartan.plugins import register_cases, register_scenes


@cartan.hookimpl
def cartan_register_media(register):
    from .helfrich import HelfrichMembrane
    from .kirchhoff_love import KirchhoffLove

    register("kirchhoff-love", KirchhoffLove)
    register("helfrich-membrane", HelfrichMembrane)


@cartan.hookimpl
def cartan_register_scenes(register):
    register_scenes(register, __file__)


@cartan.hookimpl
def cartan_register_cases(register):
    register_cases(register, f"{__package__}.cases")


def helfrich(problem, *, steps: int = 30, tau: float = 0.05, growth: float = 1.3, tau_max: float = 50.0,
             hold: tuple[str, ...] = ("area", "volume"), targets: dict[str, float] | None = None,
             hold_tol: float = 1e-10, tol: float = 1e-10, stop: float = 0.0, max_hold_iterations: int = 12,
             max_retries: int = 6, mesh: str = "step", redistribute: int = 1, motion: str = "free",
             tangential_penalty: float = 1e3, reuse: float = 0.1, pole: str = "corners",
             multipliers: str = "bordered"):
    """The ``helfrich`` flow of a scene's ``[flow]`` table:
    :func:`cartan_kirchhoff_love.vesicle.helfrich_flow` of the scene's problem (same options)."""
    from .vesicle import helfrich_flow

    return helfrich_flow(problem, steps=steps, tau=tau, growth=growth, tau_max=tau_max, hold=hold,
                         targets=targets, hold_tol=hold_tol, tol=tol, stop=stop,
                         max_hold_iterations=max_hold_iterations, max_retries=max_retries, mesh=mesh,
                         redistribute=redistribute, motion=motion, tangential_penalty=tangential_penalty,
                         reuse=reuse, pole=pole, multipliers=multipliers)


def _check_helfrich(problem, options: dict) -> None:
    """Ranges of the ``helfrich`` flow's options (``ValueError`` naming the option and its range)."""
    import math

    medium = getattr(problem.medium, "name", None)
    if medium != "helfrich-membrane":
        raise ValueError(f"the helfrich flow needs medium = 'helfrich-membrane', got {medium!r}")
    from .vesicle import _is_sphere_chart

    grid = problem.grid
    if grid.d != 2 or not (all(grid.periodic) or _is_sphere_chart(grid)):
        raise ValueError("the helfrich flow needs a closed surface: a d = 2 grid periodic along both axes (a torus) "
                         "or the sphere's chart (periodic = [true, false], glued = [-1, 0])")
    for name, low, strict in (("tau", 0.0, True), ("tau_max", 0.0, True), ("hold_tol", 0.0, True),
                              ("tol", 0.0, True), ("growth", 1.0, False), ("stop", 0.0, False)):
        if name in options:
            v = options[name]
            if not math.isfinite(v) or (v <= low if strict else v < low):
                raise ValueError(f"{name} must be {'>' if strict else '≥'} {low:g}, got {v!r}")
    for name, low in (("max_hold_iterations", 1), ("max_retries", 0), ("redistribute", 0)):
        if name in options and not low <= options[name] <= 1000:
            raise ValueError(f"{name} must be an integer in [{low}, 1000], got {options[name]!r}")
    if options.get("mesh", "step") not in ("step", "initial"):
        raise ValueError(f"mesh must be 'step' or 'initial', got {options['mesh']!r}")
    if options.get("motion", "free") not in ("free", "normal"):
        raise ValueError(f"motion must be 'free' or 'normal', got {options['motion']!r}")
    if options.get("multipliers", "bordered") not in ("bordered", "outer"):
        raise ValueError(f"multipliers must be 'bordered' or 'outer', got {options['multipliers']!r}")
    if options.get("pole", "corners") not in ("corners", "cap"):
        raise ValueError(f"pole must be 'corners' or 'cap', got {options['pole']!r}")
    if "reuse" in options and not 0.0 <= options["reuse"] < 1.0:
        raise ValueError(f"reuse must be in [0, 1), got {options['reuse']!r}")
    if "tangential_penalty" in options:
        v = options["tangential_penalty"]
        if not math.isfinite(v) or v < 1.0:
            raise ValueError(f"tangential_penalty must be ≥ 1, got {v!r}")
    hold = tuple(options.get("hold", ("area", "volume")))
    if not set(hold) <= {"area", "volume"} or len(set(hold)) != len(hold):
        raise ValueError(f"hold must list distinct entries of 'area', 'volume', got {list(hold)!r}")
    for key, value in (options.get("targets") or {}).items():
        if key not in hold or not value > 0:
            raise ValueError(f"targets: {key} must be a held quantity ({', '.join(hold) or 'none'}) with a value "
                             f"> 0, got {value!r}")


helfrich.check = _check_helfrich


@cartan.hookimpl
def cartan_register_flows(register):
    register("helfrich", helfrich)
