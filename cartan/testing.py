"""The conformance kit plugin authors run: :func:`check_medium`.

A medium is physics only; the kit checks that it fulfils the :class:`~cartan.medium.Medium`
contract and then runs it through every registered scheme × integrator on a tiny problem::

    from cartan.testing import check_medium
    report = check_medium("my-medium", params={"stiffness": 2.0})
    print(report)

Checks
------
contract
    ``inertia()`` shape ``(r,)`` and ≥ 0 (a medium that declares ``kinetic_metric()``: M
    symmetric, its diagonal ``inertia()``, invertible off the gauge rows — it may be
    indefinite); ``rest_strain()`` shape ``(d, r)``; ``potential`` and
    ``stress`` shapes and finiteness; ``parameters()`` JSON-serialisable and sufficient to
    rebuild the medium (``type(m)(**m.parameters())``).
energy consistency
    the stress is the gradient of the potential: central finite differences of U against
    ``stress`` at random strains near the rest state (relative error ≤ ``fd_rtol``; the
    central difference error is O(ε²) with ε = 1e-6, so 1e-6 leaves room for round-off
    ε_mach·|U|/ε ≈ 1e-10 relative).
runs
    a few steps of every scheme × integrator on a 5-node grid per axis: array shapes,
    finite values, group membership of the frames (defect ≤ ``defect_tol`` for geometric
    integrators), and, for ``lie-verlet`` with no loads, energy conserved to the leapfrog bound
    (ωΔt)²/8 ≤ 5e-3 of every mode at 0.1 of the CFL estimate (checked at 1e-2 relative).
    An integrator that refuses the medium with a ``ValueError`` at its first step (e.g.
    ``implicit-midpoint`` needs a diagonal kinetic metric) is skipped, with its reason; a
    medium with constrained strains is stepped only by the integrators that hold them
    (``rattle``, on the lattice).
coupled Lagrangian
    for a medium with :attr:`~cartan.medium.Medium.coupled_lagrangian` (ℓ(N, X) coupling
    velocity and strain), at small random velocities and the random strains above:
    ``velocity_at`` and ``momentum_at`` are inverse to each other (1e-10 relative, on the
    live components: both are Newton solves in general), ``velocity_at = ∂H/∂S`` and
    ``stress_with = ∂H/∂X`` (central differences of ``hamiltonian``, ≤ ``fd_rtol``
    relative), ``velocity_at`` does not depend on the gauge components of S, and
    ``stress_with``, ``hamiltonian`` and ``velocity_at`` have the contract's shapes
    (:func:`check_coupled_contract`, also usable alone).
point kernels
    for a medium that declares them (:meth:`~cartan.medium.Medium.point_kernels`): the energy
    and stress kernels agree with ``potential`` and ``stress`` to round-off (1e-12 relative) at
    the same random strains, so the compiled loops run the physics the reference path runs.
compiled loops
    for a medium with point kernels, a few ``lie-verlet`` steps on the lattice in the
    generated compiled loop agree with the reference path to round-off (1e-12 relative).
core knows no medium
    the medium's registry name is not a string constant anywhere in the core's code
    (``cartan/``, docstrings excluded): the core cannot branch on it.
"""

from __future__ import annotations

import ast
import json
import pathlib
from dataclasses import dataclass, field
from typing import Any

import numpy as np

__all__ = ["ConformanceError", "Report", "check_coupled_contract", "check_medium"]


class ConformanceError(AssertionError):
    """A medium failed the conformance kit; the message lists every failed check."""


@dataclass
class Report:
    """Outcome of :func:`check_medium`: passed checks, failures, and combinations skipped."""

    medium: str
    passed: list[str] = field(default_factory=list)
    failed: list[str] = field(default_factory=list)
    skipped: list[str] = field(default_factory=list)

    def __str__(self) -> str:
        lines = [f"conformance of medium {self.medium!r}: {len(self.passed)} passed, "
                 f"{len(self.failed)} failed, {len(self.skipped)} skipped"]
        lines += [f"  FAIL {m}" for m in self.failed]
        lines += [f"  skip {m}" for m in self.skipped]
        return "\n".join(lines)


def _core_code_strings() -> dict[str, set[str]]:
    """String constants in the core's code, docstrings excluded, per module path."""
    import cartan

    core = pathlib.Path(cartan.__file__).resolve().parent
    out: dict[str, set[str]] = {}
    for path in core.rglob("*.py"):
        tree = ast.parse(path.read_text(), filename=str(path))
        docstrings = set()
        for node in ast.walk(tree):
            if isinstance(node, ast.Module | ast.ClassDef | ast.FunctionDef | ast.AsyncFunctionDef):
                body = node.body
                if body and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant):
                    docstrings.add(id(body[0].value))
        out[str(path.relative_to(core))] = {
            node.value for node in ast.walk(tree)
            if isinstance(node, ast.Constant) and isinstance(node.value, str) and id(node) not in docstrings
        }
    return out


def _build(medium: Any, params: dict[str, Any] | None):
    import cartan
    from cartan.medium import Medium

    if isinstance(medium, str):
        return cartan.medium(medium, **(params or {}))
    if isinstance(medium, type) and issubclass(medium, Medium):
        return medium(**(params or {}))
    if isinstance(medium, Medium):
        return medium
    raise TypeError(f"check_medium needs a registered name, a Medium subclass or instance, got {medium!r}")


def _small_problem(med, rng: np.random.Generator, n: int = 5):
    """A tiny open grid with frames near a state of rest strain, slightly perturbed."""
    from cartan.grid import Grid
    from cartan.problem import InitialState, Problem

    g = med.group
    d = med.material_dim
    grid = Grid((n,) * d, length=1.0)
    coords = np.stack(np.meshgrid(*[grid.coordinates(a) for a in range(d)], indexing="ij"), axis=-1)
    X0 = med.rest_strain()
    # exp(Σ_α u_α X0_α) is the rest configuration when the rest strains commute (rods, flat
    # media); a small random perturbation of the frames excites every component.
    xi = np.einsum("...a,ak->...k", coords, X0)
    live = ~med.gauge_mask()
    pert = 0.05 * rng.standard_normal((*grid.shape, g.dim)) * live
    Phi = g.compose(g.exp(xi), g.exp(pert))
    N = 0.05 * rng.standard_normal((*grid.shape, g.dim)) * live
    return Problem(med, grid, InitialState(Phi=Phi, N=N))


def _coupled_checks(med: Any, Xs: np.ndarray, rng: np.random.Generator,
                    fd_rtol: float) -> list[tuple[str, bool, str]]:
    """``(name, ok, detail)`` of the coupled-Lagrangian checks (:func:`check_coupled_contract`)."""
    out: list[tuple[str, bool, str]] = []
    r = med.group.dim
    live = ~np.asarray(med.gauge_mask(), dtype=bool)
    n = Xs.shape[0]
    # velocities of 0.1 in the units of N on the live components: the contract's media are
    # checked near rest, where the Legendre map is invertible
    N = np.zeros((n, r))
    N[:, live] = 0.1 * rng.standard_normal((n, int(live.sum())))
    try:
        S = np.asarray(med.momentum_at(N, Xs), dtype=float)
        Nb = np.asarray(med.velocity_at(S, Xs), dtype=float)
        Sb = np.asarray(med.momentum_at(Nb, Xs), dtype=float)
        H = np.asarray(med.hamiltonian(S, Xs), dtype=float)
        Q = np.asarray(med.stress_with(S, Xs), dtype=float)
    except Exception as exc:  # noqa: BLE001 - reported as a failed check
        return [("coupled contract: momentum_at, velocity_at, hamiltonian, stress_with evaluate", False,
                 f"{type(exc).__name__}: {exc}")]
    shapes = S.shape == (n, r) and Nb.shape == (n, r) and H.shape == (n,) and Q.shape == Xs.shape
    out.append(("coupled contract: shapes of momentum_at [..., r], velocity_at [..., r], hamiltonian [...], "
                "stress_with [..., d, r]", bool(shapes), f"got {S.shape}, {Nb.shape}, {H.shape}, {Q.shape}"))
    if not shapes:
        return out
    scale_n = max(float(np.max(np.abs(N[:, live]))), 1e-300)
    scale_s = max(float(np.max(np.abs(S[:, live]))), 1e-300)
    err = max(float(np.max(np.abs((Nb - N)[:, live]))) / scale_n, float(np.max(np.abs((Sb - S)[:, live]))) / scale_s)
    out.append(("coupled contract: velocity_at and momentum_at are inverse maps", err <= 1e-10,
                f"relative error {err:.2e}"))
    gauge = S.copy()
    gauge[:, ~live] += 1.0
    Ng = np.asarray(med.velocity_at(gauge, Xs), dtype=float)
    err_g = float(np.max(np.abs(Ng - Nb), initial=0.0)) / scale_n
    out.append(("coupled contract: velocity_at ignores the gauge components of S", err_g <= 1e-10,
                f"relative change {err_g:.2e}"))
    eps = 1e-6
    fd_s = np.zeros_like(S)
    for k in np.flatnonzero(live):
        dS = np.zeros(r)
        dS[k] = eps
        fd_s[:, k] = (med.hamiltonian(S + dS, Xs) - med.hamiltonian(S - dS, Xs)) / (2 * eps)
    err_s = float(np.max(np.abs((fd_s - Nb)[:, live]))) / max(float(np.max(np.abs(fd_s[:, live]))), 1e-300)
    out.append(("coupled contract: velocity_at = ∂H/∂S (central differences)", err_s <= fd_rtol,
                f"relative error {err_s:.2e} > {fd_rtol:.0e}"))
    fd_x = np.zeros_like(Q)
    d = Xs.shape[1]
    for a in range(d):
        for k in range(r):
            dX = np.zeros((d, r))
            dX[a, k] = eps
            fd_x[:, a, k] = (med.hamiltonian(S, Xs + dX) - med.hamiltonian(S, Xs - dX)) / (2 * eps)
    err_x = float(np.max(np.abs(fd_x - Q))) / max(float(np.max(np.abs(fd_x))), 1e-300)
    out.append(("coupled contract: stress_with = ∂H/∂X (central differences)", err_x <= fd_rtol,
                f"relative error {err_x:.2e} > {fd_rtol:.0e}"))
    return out


def check_coupled_contract(medium: Any, params: dict[str, Any] | None = None, *, fd_rtol: float = 1e-6,
                           seed: int = 0, raise_on_failure: bool = True) -> Report:
    """The checks of a Lagrangian coupling N and X (module docstring, "coupled Lagrangian") alone.

    At 7 random strains ``X = rest_strain() + 0.1·noise`` ``[7, d, r]`` and velocities of 0.1
    in the units of N on the live components: the Legendre maps ``momentum_at`` and
    ``velocity_at`` inverse to each other, ``velocity_at = ∂H/∂S`` and ``stress_with = ∂H/∂X``
    by central differences of ``hamiltonian`` (step 1e-6: error O(1e-12) + round-off
    ε_mach·|H|/1e-6, far below ``fd_rtol``).

    Parameters
    ----------
    medium : str, Medium subclass or Medium instance
        With ``coupled_lagrangian`` set.
    params : dict, optional
        Constructor keywords when ``medium`` is a name or a class.
    fd_rtol : float
        Relative tolerance of the finite-difference checks.
    seed : int
        Of the random strains and velocities.
    raise_on_failure : bool
        Raise :class:`ConformanceError` listing the failures (default); otherwise return the report.

    Raises
    ------
    ValueError
        When the medium does not declare ``coupled_lagrangian``.
    """
    med = _build(medium, params)
    if not getattr(med, "coupled_lagrangian", False):
        raise ValueError(f"medium {med.name or type(med).__name__!r} does not declare coupled_lagrangian: "
                         "check_medium covers its contract")
    rng = np.random.default_rng(seed)
    rep = Report(med.name or type(med).__name__)
    Xs = np.asarray(med.rest_strain(), dtype=float) + 0.1 * rng.standard_normal((7, *np.shape(med.rest_strain())))
    for name, ok, detail in _coupled_checks(med, Xs, rng, fd_rtol):
        (rep.passed if ok else rep.failed).append(name if ok else f"{name}: {detail}")
    if rep.failed and raise_on_failure:
        raise ConformanceError(str(rep))
    return rep


def check_medium(medium: Any, params: dict[str, Any] | None = None, *, schemes: list[str] | None = None,
                 integrators: list[str] | None = None, steps: int = 5, fd_rtol: float = 1e-6,
                 defect_tol: float = 1e-10, seed: int = 0, raise_on_failure: bool = True,
                 compiled: bool = True) -> Report:
    """Run the conformance kit on a medium (see the module docstring for the checks).

    Parameters
    ----------
    medium : str, Medium subclass or Medium instance
    params : dict, optional
        Constructor keywords when ``medium`` is a name or a class.
    schemes, integrators : list of str, optional
        Registered names to run (default: all registered, ``kinematic`` with N = 0).
    steps : int
        Steps per combination.
    raise_on_failure : bool
        Raise :class:`ConformanceError` listing the failures (default); otherwise return the
        report.
    compiled : bool
        For a medium with point kernels, also run ``lie-verlet`` on the lattice in its
        generated compiled loop and compare with the reference path (default True; the first
        run on a machine compiles the loop).

    Returns
    -------
    Report
    """
    import cartan
    from cartan.problem import Damping, Problem

    rng = np.random.default_rng(seed)
    med = _build(medium, params)
    rep = Report(med.name or type(med).__name__)
    g, d, r = med.group, med.material_dim, med.group.dim

    def check(name: str, ok: bool, detail: str = "") -> bool:
        (rep.passed if ok else rep.failed).append(name if ok else f"{name}: {detail}")
        return ok

    # ---------------------------------------------------------------- contract
    m = np.asarray(med.inertia(), dtype=float)
    if med._diagonal_metric():
        check("inertia shape (r,) and ≥ 0", m.shape == (r,) and bool(np.all(m >= 0)), f"got {m!r}")
    else:  # a declared metric may be non-diagonal and indefinite (a relativistic string)
        M = np.asarray(med.kinetic_metric(), dtype=float)
        live = ~np.asarray(med.gauge_mask(), dtype=bool)
        ok = (M.shape == (r, r) and m.shape == (r,) and bool(np.allclose(M, M.T)) and bool(np.allclose(np.diag(M), m))
              and int(np.linalg.matrix_rank(M[np.ix_(live, live)])) == int(live.sum()))
        check("kinetic metric (r, r): symmetric, diagonal = inertia(), invertible off the gauge rows", ok,
              f"got {M!r}")
    X0 = np.asarray(med.rest_strain(), dtype=float)
    check("rest_strain shape (d, r)", X0.shape == (d, r), f"got shape {X0.shape}")
    Xs = X0 + 0.1 * rng.standard_normal((7, d, r))
    U, Q = np.asarray(med.potential(Xs)), np.asarray(med.stress(Xs))
    check("potential shape [...]", U.shape == (7,), f"got {U.shape}")
    check("stress shape [..., d, r]", Q.shape == (7, d, r), f"got {Q.shape}")
    check("potential and stress finite", bool(np.all(np.isfinite(U)) and np.all(np.isfinite(Q))))
    try:
        p = med.parameters()
        json.dumps(p)
        twin = type(med)(**p)
        ok = np.allclose(twin.stress(Xs), Q) and np.allclose(twin.inertia(), m)
        check("parameters() is JSON and rebuilds the medium", bool(ok), "rebuilt medium differs")
    except Exception as exc:  # noqa: BLE001 - reported as a failed check
        check("parameters() is JSON and rebuilds the medium", False, f"{type(exc).__name__}: {exc}")

    # ---------------------------------------------------------------- energy consistency
    eps = 1e-6
    worst = 0.0
    for X in Xs[:3]:
        fd = np.empty((d, r))
        for a in range(d):
            for k in range(r):
                dX = np.zeros((d, r))
                dX[a, k] = eps
                fd[a, k] = (float(med.potential(X + dX)) - float(med.potential(X - dX))) / (2 * eps)
        scale = max(float(np.max(np.abs(fd))), 1e-300)
        worst = max(worst, float(np.max(np.abs(fd - med.stress(X)))) / scale)
    check("stress = ∂U/∂X (central differences)", worst <= fd_rtol, f"relative error {worst:.2e} > {fd_rtol:.0e}")

    # ---------------------------------------------------------------- coupled Lagrangian
    if getattr(med, "coupled_lagrangian", False):
        for name, ok, detail in _coupled_checks(med, Xs, rng, fd_rtol):
            check(name, ok, detail)

    # ---------------------------------------------------------------- point kernels
    kernels = med.point_kernels()
    if kernels is not None:
        params_k = np.ascontiguousarray(kernels.params, dtype=float).ravel()
        worst_k = 0.0
        for X in Xs:
            Qk = np.empty((d, r))
            kernels.stress(np.ascontiguousarray(X), np.ascontiguousarray(X0), params_k, Qk)
            Uk = float(kernels.energy(np.ascontiguousarray(X), np.ascontiguousarray(X0), params_k))
            scale = max(float(np.max(np.abs(Q))), abs(float(np.max(np.abs(U)))), 1e-300)
            worst_k = max(worst_k, float(np.max(np.abs(Qk - med.stress(X)))) / scale,
                          abs(Uk - float(med.potential(X))) / scale)
        # the kernels and the vectorised methods evaluate one formula in two orders: round-off
        check("point kernels agree with potential() and stress()", worst_k <= 1e-12,
              f"relative difference {worst_k:.2e}")

    # ---------------------------------------------------------------- core knows no medium
    if med.name:
        hits = sorted(path for path, consts in _core_code_strings().items() if med.name in consts)
        check("the core never names the medium in code", not hits, f"named in {hits}")

    # ---------------------------------------------------------------- runs
    scheme_names = schemes or sorted(cartan.registry("schemes"))
    integ_names = integrators or sorted(cartan.registry("integrators"))
    if med.constrained_strains() is not None:  # only the integrators that hold them step the medium
        registry = cartan.registry("integrators")
        held = [n for n in integ_names if getattr(registry[n], "constrained", False)]
        rep.skipped.append(f"time integration with {', '.join(sorted(set(integ_names) - set(held)))}: the medium "
                           "holds strain components fixed (constrained_strains) and they do not")
        integ_names, compiled = held, False
    base = _small_problem(med, rng)
    for sname in scheme_names:
        for iname in integ_names:
            label = f"{sname} × {iname}"
            loads = [Damping(np.where(med.gauge_mask(), 0.0, 1.0))] if iname == "overdamped" else []
            problem = Problem(med, base.grid, base.initial, loads=loads)
            try:
                scheme = cartan.registry("schemes")[sname](problem, track_frames=True)
            except ValueError as exc:
                rep.skipped.append(f"{label}: {exc}")
                continue
            scheme.compiled_diagnostics = compiled  # (no compiled code at all when the compiled loops are not checked)
            opts = {"velocity": lambda t, u, X: np.zeros(r)} if iname == "kinematic" else {}
            integ = cartan.registry("integrators")[iname](**opts)
            try:
                state = scheme.initial_state()
                E0 = scheme.kinetic_energy(state) + scheme.potential_energy(state)
                lv = cartan.registry("integrators")["lie-verlet"]()
                dt = 0.1 * (integ.dt_max(scheme, state) if np.isfinite(integ.dt_max(scheme, state))
                            and integ.dt_max(scheme, state) > 0 else lv.dt_max(scheme, state))
                try:
                    integ.step(scheme, state, dt)
                except ValueError as exc:  # the integrator does not apply to this medium (it says why)
                    rep.skipped.append(f"{label}: {exc}")
                    continue
                for _ in range(steps - 1):
                    integ.step(scheme, state, dt)
                Phi = scheme.frames(state)
                ok = (state.S.shape == (*base.grid.shape, r) and Phi.shape[-2:] == (g.matrix_size,) * 2
                      and state.is_finite())
                if not check(f"{label}: shapes and finite values", ok, "bad shape or non-finite state"):
                    continue
                if integ.geometric:
                    defect = float(np.max(g.defect(Phi)))
                    check(f"{label}: frames stay in {g.name}", defect <= defect_tol, f"defect {defect:.2e}")
                if iname == "lie-verlet":
                    E1 = scheme.kinetic_energy(state) + scheme.potential_energy(state)
                    err = abs(E1 - E0) / max(abs(E0), 1e-300)
                    # leapfrog's energy error per mode is ≤ (ωΔt)²/8 = 5e-3 at Δt = 0.1·2/ω_max
                    check(f"{label}: energy conserved", err <= 1e-2, f"relative energy error {err:.2e}")
            except Exception as exc:  # noqa: BLE001 - reported as a failed check
                check(f"{label}: runs", False, f"{type(exc).__name__}: {exc}")
    # ---------------------------------------------------------------- compiled loops
    if kernels is not None and compiled and "lattice" in scheme_names:
        from cartan.simulate import simulate

        problem = Problem(med, base.grid, base.initial)
        label = "lattice × lie-verlet compiled"
        try:
            scheme = cartan.registry("schemes")["lattice"](problem)
            ops = scheme.compiled_operators()
            if ops is None or not ops.ok:
                rep.skipped.append(f"{label}: {getattr(ops, 'reason', 'no operator set')}")
            else:
                dt = 0.1 * cartan.registry("integrators")["lie-verlet"]().dt_max(scheme, scheme.initial_state())
                kw = dict(integrator="lie-verlet", dt=dt, t_end=steps * dt, save_every=steps, progress=False)
                fast, ref = simulate(problem, **kw), simulate(problem, **kw, compiled=False)
                err = max(float(np.max(np.abs(fast[k].values - ref[k].values)))
                          / max(float(np.max(np.abs(ref[k].values))), 1e-300) for k in ("S", "X"))
                # one formula in two orders over a few steps: round-off
                check(f"{label}: agrees with the reference path", err <= 1e-12, f"relative difference {err:.2e}")
        except Exception as exc:  # noqa: BLE001 - reported as a failed check
            check(f"{label}: runs", False, f"{type(exc).__name__}: {exc}")
    if rep.failed and raise_on_failure:
        raise ConformanceError(str(rep))
    return rep
