"""The elastic string's reduced Lagrangian, momentum and stress (docs/media/relativistic-rod.md §2).

Covariant reference formulas in numpy, point by point, for checking the derivation, and their
temporal-gauge forms (r = (ct, x⃗): ``temporal_*``, with the Hessian and the inverse Legendre
map) that :class:`cartan_relativistic.elastic_rod.ElasticRelativisticRod` runs through the
core's coupled-Lagrangian path.  With ṙ = ∂_t r, r′ = ∂_u r (4-vectors, r⁰ = ct),
A = −⟨ṙ, ṙ⟩, B = ⟨ṙ, r′⟩, C = ⟨r′, r′⟩ and the rest-frame stretch λ = √(C + B²/A):

    ℓ = −ε(λ) √A / c,
    S_y = ∂ℓ/∂ṙ = (ε/c) ηṙ/√A − (T/c)(B/√A) ηn,      Q_y = −∂ℓ/∂r′ = T (√A/c) ηn,

with T = ε′(λ) and n = (r′ + (B/A)ṙ)/λ the unit rest-frame tangent.
"""

from __future__ import annotations

import inspect
import re
import threading
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

__all__ = ["ETA", "LAW_ENTRY_POINT_GROUP", "ElasticLaw", "as_law", "lagrangian", "law_from_repr", "law_names",
           "make_law", "momentum_stress", "newtonian_expansion", "quadratic_law", "register_law", "stretch",
           "temporal_hessian", "temporal_lagrangian", "temporal_momentum", "temporal_stress", "temporal_velocity"]

#: Minkowski metric η = diag(−1, 1, 1, 1)
ETA = np.array([-1.0, 1.0, 1.0, 1.0])


def _mink(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.sum(ETA * a * b, axis=-1)


def stretch(rdot: np.ndarray, rprime: np.ndarray) -> np.ndarray:
    """Rest-frame stretch λ = √(⟨r′, r′⟩ + ⟨ṙ, r′⟩²/(−⟨ṙ, ṙ⟩)), ``[..., 4]`` → ``[...]``."""
    A = -_mink(rdot, rdot)
    B = _mink(rdot, rprime)
    return np.sqrt(_mink(rprime, rprime) + B * B / A)


def lagrangian(rdot: np.ndarray, rprime: np.ndarray, eps: Callable, c: float) -> np.ndarray:
    """ℓ = −ε(λ)√A/c per unit reference length and unit time, ``[..., 4]`` → ``[...]``."""
    A = -_mink(rdot, rdot)
    return -eps(stretch(rdot, rprime)) * np.sqrt(A) / c


def momentum_stress(rdot: np.ndarray, rprime: np.ndarray, eps: Callable, deps: Callable,
                    c: float) -> tuple[np.ndarray, np.ndarray]:
    """``(S_y, Q_y)``, each ``[..., 4]`` (covariant components, ηṙ lowered), from the closed forms above."""
    A = -_mink(rdot, rdot)
    B = _mink(rdot, rprime)
    lam = stretch(rdot, rprime)
    n = (rprime + (B / A)[..., None] * rdot) / lam[..., None]
    sA = np.sqrt(A)[..., None]
    T = deps(lam)[..., None]
    S = (eps(lam)[..., None] / c) * ETA * rdot / sA - (T / c) * (B[..., None] / sA) * ETA * n
    Q = T * (sA / c) * ETA * n
    return S, Q


def newtonian_expansion(v: np.ndarray, xprime: np.ndarray, m: float, W: Callable, dW: Callable,
                        c: float) -> tuple[np.ndarray, np.ndarray]:
    """The c⁰ and c⁻² terms of ℓ + mc² for ε = mc² + W(λ), lab time (r = (ct, x⃗)).

    Returns
    -------
    (l0, l2) : arrays ``[...]``
        ``l0 = ½m|v|² − W(|x′|)`` and ``l2 = c⁻²[⅛m v⁴ + ½W v² − ½W′(|x′|)|x′|(v·x̂′)²]``.
    """
    v2 = np.sum(v * v, axis=-1)
    L = np.linalg.norm(xprime, axis=-1)
    vt = np.sum(v * xprime, axis=-1) / L
    l0 = 0.5 * m * v2 - W(L)
    l2 = (m * v2 * v2 / 8.0 + 0.5 * W(L) * v2 - 0.5 * dW(L) * L * vt * vt) / c**2
    return l0, l2


# ---------------------------------------------------------------------------- the law ε(λ)
class ElasticLaw:
    """The elastic part ``W(λ) = ε(λ) − μc²`` of a rest-frame energy per unit reference length,
    with its derivatives ``W′`` (the tension T = ε′ = W′) and ``W″`` (docs §2, "General ε(λ)").

    Parameters
    ----------
    energy, tension, stiffness : callable
        ``W(λ)``, ``W′(λ)`` and ``W″(λ)``, elementwise on arrays of stretches ``[...]``.
    name : str, optional
        A label for ``repr`` and error messages.

    Notes
    -----
    The medium checks the law on construction (:meth:`check`): finite values, the derivatives
    consistent with ``W`` (central differences), and, with ε = μc² + W, on the stretches
    checked (λ = 1 and the medium's ``stretch_range``)

        ε > 0,   ε″ > 0   and   c_L² = c² λ²ε″/(ε − λε′) < c²  ⇔  ε − λε′ − λ²ε″ > 0,

    the longitudinal waves real and slower than light; then ε − λε′ > 0 as well, so the
    transverse waves, at c_T² = c² λε′/ε, are slower than light and the kinetic Hessian
    ∂²ℓ/∂v⃗² is positive definite at rest (the Legendre map is invertible near v⃗ = 0).

    **Records.** A run stores its problem, the law included, in its output and checkpoint, and
    a restart rebuilds the medium from that record.  A law made by name from the registry
    (:func:`make_law`, the classmethods :meth:`quadratic` and :meth:`quartic`, or a law given
    to the medium as ``"name"`` or ``{"name": ..., **parameters}``) carries its record
    ``{"name": ..., **parameters}`` (:meth:`to_dict`); a law built from bare callables has
    none, and :meth:`to_dict` raises ``ValueError`` saying how to register it
    (:func:`register_law`).
    """

    def __init__(self, energy: Callable, tension: Callable, stiffness: Callable, name: str = "custom"):
        for key, f in (("energy", energy), ("tension", tension), ("stiffness", stiffness)):
            if not callable(f):
                raise ValueError(f"ElasticLaw {key} must be a callable W, W′ or W″ of the stretch λ, got {f!r}")
        self.W, self.dW, self.ddW = energy, tension, stiffness
        self.name = str(name)
        #: ``{"name": registered name, **parameters}`` when made by :func:`make_law`, else None
        self.record: dict[str, Any] | None = None

    @classmethod
    def quadratic(cls, k: float) -> ElasticLaw:
        """``W = ½k(λ − 1)²``, ``W′ = k(λ − 1)``, ``W″ = k`` (the registered law ``"quadratic"``)."""
        return make_law("quadratic", k=k)

    @classmethod
    def quartic(cls, k: float, q: float) -> ElasticLaw:
        """``W = ½k(λ − 1)² + ¼q(λ − 1)⁴``, ``W′ = k(λ − 1) + q(λ − 1)³``, ``W″ = k + 3q(λ − 1)²``
        (the registered law ``"quartic"``)."""
        return make_law("quartic", k=k, q=q)

    def to_dict(self) -> dict[str, Any]:
        """The law's record ``{"name": registered name, **parameters}`` (JSON values), from which
        :func:`as_law` rebuilds it.

        Raises
        ------
        ValueError
            For a law built from bare callables (no registered name): it could not be rebuilt
            from a run's output, so a restart would not be exact.
        """
        if self.record is None:
            raise ValueError(
                f"law {self.name!r} is built from bare callables and cannot be recorded in a run's output and "
                "checkpoint (a restart could not rebuild it); register it by name — "
                "cartan_relativistic.elastic.register_law('my-law', factory), factory(**parameters) returning the "
                "ElasticLaw (or the ElasticLaw itself) — and give law='my-law' or {'name': 'my-law', **parameters}; "
                f"registered laws: {', '.join(law_names())}")
        return dict(self.record)

    def cartan_record(self) -> dict[str, Any]:
        """What :func:`cartan.io.to_json` writes for this law: :meth:`to_dict` (which raises
        for an unregistered law, never a silent ``repr``)."""
        return self.to_dict()

    @classmethod
    def from_dict(cls, record: Mapping[str, Any]) -> ElasticLaw:
        """The law of a record ``{"name": ..., **parameters}`` (:func:`as_law`)."""
        return as_law(dict(record))

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, ElasticLaw):
            return NotImplemented
        if self.record is not None or other.record is not None:
            return self.record == other.record
        return self is other

    def __hash__(self) -> int:
        return hash(repr(sorted(self.record.items()))) if self.record is not None else id(self)

    def functions(self, mu: float, c: float) -> tuple[Callable, Callable, Callable]:
        """``(ε, ε′, ε″)`` with ε = μc² + W, elementwise (the ``law`` tuple of this module)."""
        rest = mu * c * c
        return ((lambda lam: rest + self.W(lam)), self.dW,
                (lambda lam: np.broadcast_to(np.asarray(self.ddW(lam), dtype=float), np.shape(lam)).copy()))

    def speeds(self, lam: np.ndarray, mu: float, c: float) -> tuple[np.ndarray, np.ndarray]:
        """Squared longitudinal and transverse wave speeds in the rest frame at the stretch λ ``[...]``:
        ``c_L² = c²λ²ε″/(ε − λε′)`` and ``c_T² = c²λε′/ε`` (docs §2, "General ε(λ)")."""
        lam = np.asarray(lam, dtype=float)
        eps, deps, ddeps = (f(lam) for f in self.functions(mu, c))
        return c * c * lam * lam * ddeps / (eps - lam * deps), c * c * lam * deps / eps

    def check(self, mu: float, c: float, stretches: np.ndarray) -> None:
        """Raise ``ValueError`` (naming ``law``) unless W, W′, W″ are finite and consistent and
        ε > 0, ε″ > 0 and ε − λε′ − λ²ε″ > 0 at every stretch given (class notes)."""
        lam = np.asarray(stretches, dtype=float)
        eps, deps, ddeps = (np.asarray(f(lam), dtype=float) * np.ones_like(lam) for f in self.functions(mu, c))
        if not (np.all(np.isfinite(eps)) and np.all(np.isfinite(deps)) and np.all(np.isfinite(ddeps))):
            raise ValueError(f"law {self.name}: W, W′ and W″ must be finite for λ in [{float(lam.min())!r}, "
                             f"{float(lam.max())!r}]")
        h = 1e-5
        at = np.union1d(lam, [0.9, 0.95, 1.05, 1.1])  # (around the rest state too: W(1) = W′(1) = 0 is common)
        for f, df, what in ((self.W, self.dW, "W′"), (self.dW, self.ddW, "W″")):
            fd = (np.asarray(f(at + h), dtype=float) - np.asarray(f(at - h), dtype=float)) / (2 * h)
            exact = np.asarray(df(at), dtype=float) * np.ones_like(at)
            # central differences err by h²f‴/6 + round-off ε|f|/h ≈ 1e-11 of the scales: 1e-6 is far above
            scale = float(np.max(np.abs(exact))) + float(np.max(np.abs(np.asarray(f(at), dtype=float))))
            bad = np.abs(fd - exact) > 1e-6 * max(scale, 1e-300)
            if np.any(bad):
                raise ValueError(f"law {self.name}: {what} is not the derivative of the previous function "
                                 f"(central differences disagree at λ = {float(at[bad][0]):.6g})")
        for ok, what in ((eps > 0, "ε(λ) = μc² + W > 0"), (ddeps > 0, "ε″ = W″ > 0 (real longitudinal waves)"),
                         (eps - lam * deps - lam * lam * ddeps > 0,
                          "ε − λε′ − λ²ε″ > 0 (longitudinal waves c_L² = c²λ²ε″/(ε − λε′) slower than light)")):
            if not np.all(ok):
                raise ValueError(f"law {self.name} must have {what} for λ in [{float(lam.min())!r}, "
                                 f"{float(lam.max())!r}]; violated at λ = {float(lam[~ok][0]):.6g}")

    def __repr__(self) -> str:
        if self.record is not None:
            args = ", ".join(f"{k}={v!r}" for k, v in self.record.items() if k != "name")
            return f"ElasticLaw({self.record['name']}({args}))"
        return f"ElasticLaw({self.name})"


# ---------------------------------------------------------------------------- the registry of laws
#: the entry-point group a distribution declares laws in (``name = "module:factory"``), read on
#: the first lookup of a name not registered in the session
LAW_ENTRY_POINT_GROUP = "cartan_relativistic.laws"

_LAWS: dict[str, Callable[..., ElasticLaw] | ElasticLaw] = {}
_LOCK = threading.Lock()
_ENTRY_POINTS_READ = [False]


def _quadratic(k: float) -> ElasticLaw:
    k = float(k)
    return ElasticLaw(lambda lam: 0.5 * k * (lam - 1.0) ** 2, lambda lam: k * (lam - 1.0),
                      lambda lam: np.full_like(np.asarray(lam, dtype=float), k), name=f"quadratic(k={k!r})")


def _quartic(k: float, q: float) -> ElasticLaw:
    k, q = float(k), float(q)
    return ElasticLaw(lambda lam: 0.5 * k * (lam - 1.0) ** 2 + 0.25 * q * (lam - 1.0) ** 4,
                      lambda lam: k * (lam - 1.0) + q * (lam - 1.0) ** 3,
                      lambda lam: k + 3.0 * q * (lam - 1.0) ** 2, name=f"quartic(k={k!r}, q={q!r})")


def register_law(name: str, law: Callable[..., ElasticLaw] | ElasticLaw, replace: bool = False) -> None:
    """Register an elastic law by name, so that runs with it record ``{"name": name, **parameters}``
    and restart exactly (:meth:`ElasticLaw.to_dict`).

    Parameters
    ----------
    name : str
        A non-empty name (``"quadratic"`` and ``"quartic"`` are built in).
    law : callable or ElasticLaw
        A factory ``law(**parameters) -> ElasticLaw`` (parameters: JSON values, numbers or
        strings), or one fixed :class:`ElasticLaw` (no parameters; it is given its record and
        can then be passed to the medium itself).
    replace : bool
        Allow replacing a registered name (otherwise ``ValueError``).

    Notes
    -----
    A distribution can declare laws in the entry-point group :data:`LAW_ENTRY_POINT_GROUP`
    (``[project.entry-points."cartan_relativistic.laws"]``, ``my-law = "pkg.module:factory"``):
    they are loaded on the first lookup of a name not registered in the session.
    """
    if not isinstance(name, str) or not name.strip():
        raise ValueError(f"law name must be a non-empty string, got {name!r}")
    if not (isinstance(law, ElasticLaw) or callable(law)):
        raise ValueError(f"law must be an ElasticLaw or a factory returning one, got {law!r}")
    with _LOCK:
        if name in _LAWS and not replace and _LAWS[name] is not law:
            raise ValueError(f"law {name!r} is already registered; pass replace=True to replace it")
        _LAWS[name] = law
    if isinstance(law, ElasticLaw):
        law.record = {"name": name}


def _entry_point_laws() -> None:
    if _ENTRY_POINTS_READ[0]:
        return
    _ENTRY_POINTS_READ[0] = True
    import importlib.metadata as md

    for ep in md.entry_points(group=LAW_ENTRY_POINT_GROUP):
        if ep.name not in _LAWS:
            try:
                register_law(ep.name, ep.load())
            except Exception as exc:  # noqa: BLE001 - a broken plugin is named, the rest keeps working
                import warnings

                warnings.warn(f"elastic law {ep.name!r} ({ep.value}) could not be loaded: {exc}", stacklevel=2)


def law_names() -> tuple[str, ...]:
    """The registered law names (built in, :func:`register_law`, entry points), sorted."""
    _entry_point_laws()
    return tuple(sorted(_LAWS))


def _json_value(law: str, key: str, value: Any) -> Any:
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, np.ndarray):
        value = value.tolist()
    if isinstance(value, (list, tuple)):
        return [_json_value(law, key, v) for v in value]
    if value is None or isinstance(value, (bool, int, float, str)):
        return value
    raise ValueError(f"law {law!r}: parameter {key} must be a number, a string or a list of them (a value a "
                     f"run's record can hold), got {value!r}")


def make_law(name: str, **parameters: Any) -> ElasticLaw:
    """The registered law ``name`` with ``parameters``, carrying its record.

    Raises
    ------
    ValueError
        An unknown name (naming the registered ones), parameters the factory does not take
        (naming its signature), or parameters that are not JSON values.
    """
    if isinstance(name, str) and name not in _LAWS:
        _entry_point_laws()
    entry = _LAWS.get(name) if isinstance(name, str) else None
    if entry is None:
        raise ValueError(f"law must be a registered name, one of {', '.join(law_names())} "
                         f"(cartan_relativistic.elastic.register_law adds one), got {name!r}")
    params = {str(k): _json_value(name, k, v) for k, v in parameters.items()}
    if isinstance(entry, ElasticLaw):
        if params:
            raise ValueError(f"law {name!r} is a fixed law and takes no parameters, got {sorted(params)}")
        return entry
    try:
        law = entry(**params)
    except TypeError as exc:
        try:
            sig = str(inspect.signature(entry))
        except (TypeError, ValueError):
            sig = "(...)"
        raise ValueError(f"law {name!r} takes the parameters {sig}, got {params!r} ({exc})") from None
    if not isinstance(law, ElasticLaw):
        raise ValueError(f"the factory of law {name!r} must return an ElasticLaw, got {law!r}")
    law.record = {"name": name, **params}
    return law


def as_law(spec: Any) -> ElasticLaw:
    """An :class:`ElasticLaw` from what the medium's ``law`` accepts: an ElasticLaw, a tuple
    ``(W, W′, W″)`` of callables (unregistered), a registered name, or a record
    ``{"name": ..., **parameters}`` (:meth:`ElasticLaw.to_dict`, a scene's inline table).

    Raises
    ------
    ValueError
        Naming ``law`` and the accepted forms.
    """
    if isinstance(spec, ElasticLaw):
        return spec
    if isinstance(spec, tuple) and len(spec) == 3:
        return ElasticLaw(*spec)
    if isinstance(spec, str):
        return make_law(spec)
    if isinstance(spec, Mapping):
        params = dict(spec)
        name = params.pop("name", None)
        if not isinstance(name, str):
            raise ValueError(f"law given as a table needs its registered name, {{'name': ..., **parameters}}; "
                             f"got {spec!r}")
        return make_law(name, **params)
    raise ValueError(f"law must be an ElasticLaw, a tuple (W, W′, W″) of callables, a registered name or "
                     f"{{'name': ..., **parameters}}, got {spec!r}")


register_law("quadratic", _quadratic)
register_law("quartic", _quartic)

#: the built-in laws as files written before laws were recorded by name hold them: their ``repr``,
#: ``ElasticLaw(quadratic(k=…))`` or ``ElasticLaw(quartic(k=…, q=…))`` (floats by their exact repr)
_PRESET_REPR = re.compile(r"^(?:ElasticLaw\()?(quadratic|quartic)\(k=([^,()\s]+)(?:, q=([^,()\s]+))?\)\)?$")


def law_from_repr(text: Any) -> ElasticLaw | None:
    """The built-in law a record written before laws were recorded by name holds, or None.

    Such a record is the law's ``repr``: ``"ElasticLaw(quartic(k=0.25, q=0.5))"`` for a preset
    (:meth:`ElasticLaw.quadratic`, :meth:`ElasticLaw.quartic`), which determines the law exactly
    (every parameter written as the ``repr`` of its float, checked to read back to the same
    text); ``"ElasticLaw(custom)"`` or the names of bare functions for any other law, which
    determine nothing (None).
    """
    if not isinstance(text, str):
        return None
    m = _PRESET_REPR.match(text)
    if m is None or text.startswith("ElasticLaw(") != text.endswith("))"):
        return None
    name, *args = m.groups()
    if (name == "quartic") != (args[1] is not None):
        return None
    values = []
    for a in args:
        if a is None:
            continue
        try:
            v = float(a)
        except ValueError:
            return None
        if repr(v) != a:  # (not the exact repr of a float: not written by ElasticLaw's repr)
            return None
        values.append(v)
    return make_law(name, **dict(zip(("k", "q"), values, strict=False)))


# ---------------------------------------------------------------------------- temporal gauge
def quadratic_law(mu: float, k: float, c: float) -> tuple[Callable, Callable, Callable]:
    """``ε(λ) = μc² + ½k(λ − 1)²``, ``T = ε′(λ) = k(λ − 1)`` and ``ε″ = k``, elementwise."""
    return ((lambda lam: mu * c * c + 0.5 * k * (lam - 1.0) ** 2), (lambda lam: k * (lam - 1.0)),
            (lambda lam: np.full_like(lam, k)))


def _gauge_parts(v: np.ndarray, x: np.ndarray, c: float) -> tuple[np.ndarray, ...]:
    """a = √A = √(c² − v²), g = 1/a², b = B = v⃗·x⃗′, λ and ∂λ/∂v⃗ (docs §2, "Temporal gauge")."""
    a2 = c * c - np.sum(v * v, axis=-1)
    g = 1.0 / a2
    b = np.sum(v * x, axis=-1)
    lam = np.sqrt(np.sum(x * x, axis=-1) + b * b * g)
    dlam = (b * g)[..., None] * (x + (b * g)[..., None] * v) / lam[..., None]
    return np.sqrt(a2), g, b, lam, dlam


def temporal_lagrangian(v: np.ndarray, x: np.ndarray, law: tuple, c: float) -> np.ndarray:
    """ℓ(v⃗, x⃗′) = −ε(λ)√(c² − v²)/c in the temporal gauge r = (ct, x⃗), ``[..., 3]`` → ``[...]``."""
    a, _, _, lam, _ = _gauge_parts(v, x, c)
    return -law[0](lam) * a / c


def temporal_momentum(v: np.ndarray, x: np.ndarray, law: tuple, c: float) -> np.ndarray:
    """p⃗ = ∂ℓ/∂v⃗ = [ε v⃗/a − T a ∂λ/∂v⃗]/c, ``[..., 3]`` (the spatial part of S_y in §2)."""
    a, _, _, lam, dlam = _gauge_parts(v, x, c)
    return ((law[0](lam) / a)[..., None] * v - (law[1](lam) * a)[..., None] * dlam) / c


def temporal_stress(v: np.ndarray, x: np.ndarray, law: tuple, c: float) -> np.ndarray:
    """Q⃗ = −∂ℓ/∂x⃗′ = (T a/c) ∂λ/∂x⃗′ = (T a/c)(x⃗′ + (B/A) v⃗)/λ, ``[..., 3]`` (spatial part of Q_y)."""
    a, g, b, lam, _ = _gauge_parts(v, x, c)
    return (law[1](lam) * a / (c * lam))[..., None] * (x + (b * g)[..., None] * v)


def temporal_hessian(v: np.ndarray, x: np.ndarray, law: tuple, c: float) -> np.ndarray:
    """∂p⃗/∂v⃗ = ∂²ℓ/∂v⃗², ``[..., 3, 3]``: with q = λ², ∂²q = 2g x x + 4bg²(x v + v x) + 2b²g² I
    + 8b²g³ v v, ∂²λ = ∂²q/(2λ) − ∂λ ∂λ/λ, ∂a = −v/a, ∂²a = −I/a − v v/a³ and
    ∂²ℓ = −[ε″ a ∂λ∂λ + T(∂λ ∂a + ∂a ∂λ) + T a ∂²λ + ε ∂²a]/c."""
    a, g, b, lam, dlam = _gauge_parts(v, x, c)
    eye = np.eye(3)
    outer = np.einsum
    xx, vv, xv = outer("...i,...j->...ij", x, x), outer("...i,...j->...ij", v, v), outer("...i,...j->...ij", x, v)
    e = lambda s: s[..., None, None]  # noqa: E731 - scalar per point against a matrix
    Hq = 2 * e(g) * xx + 4 * e(b * g * g) * (xv + np.swapaxes(xv, -1, -2)) + 2 * e(b * b * g * g) * eye \
        + 8 * e(b * b * g**3) * vv
    Hlam = Hq / (2 * e(lam)) - outer("...i,...j->...ij", dlam, dlam) / e(lam)
    da = -v / a[..., None]
    Ha = -eye / e(a) - vv / e(a**3)
    T = law[1](lam)
    cross = outer("...i,...j->...ij", dlam, da)
    return -(e(law[2](lam) * a) * outer("...i,...j->...ij", dlam, dlam) + e(T) * (cross + np.swapaxes(cross, -1, -2))
             + e(T * a) * Hlam + e(law[0](lam)) * Ha) / c


def _newton(p: np.ndarray, x: np.ndarray, v: np.ndarray, law: tuple, c: float, iterations: int) -> np.ndarray | None:
    """Newton's method for p⃗(v⃗) = p⃗ from ``v`` (see :func:`temporal_velocity`); None if it fails."""
    done = False
    with np.errstate(invalid="ignore", divide="ignore"):
        for _ in range(iterations):
            R = temporal_momentum(v, x, law, c) - p
            J = temporal_hessian(v, x, law, c)
            if not (np.all(np.isfinite(R)) and np.all(np.isfinite(J))):
                return None
            try:
                dv = np.linalg.solve(J, R[..., None])[..., 0]
            except np.linalg.LinAlgError:
                return None
            alpha = np.ones((*v.shape[:-1], 1))
            for _ in range(60):  # stay inside the light cone
                out = np.linalg.norm(v - alpha * dv, axis=-1, keepdims=True) >= c
                if not np.any(out):
                    break
                alpha = np.where(out, 0.5 * alpha, alpha)
            v = v - alpha * dv
            if done:
                return v
            scale = np.maximum(np.linalg.norm(v, axis=-1), 1e-3 * c)
            done = bool(np.all(np.linalg.norm(dv, axis=-1) <= 1e-12 * scale) and np.all(alpha == 1.0))
    return None


def temporal_velocity(p: np.ndarray, x: np.ndarray, law: tuple, c: float, iterations: int = 40,
                      start: np.ndarray | None = None) -> np.ndarray:
    """The inverse Legendre map v⃗(p⃗, x⃗′) ``[..., 3]``: Newton per point on p⃗(v⃗) = p⃗.

    The Jacobian is the closed-form Hessian (:func:`temporal_hessian`), the start the
    Newtonian v⃗ = c²p⃗/ε(|x⃗′|) pulled inside the light cone, and a step that would leave the
    light cone is halved until it does not.  Once every correction is below 10⁻¹² of
    max(|v⃗|, 10⁻³c) one more step is taken (quadratic convergence: the result is at round-off).
    When that fails (fast motion along the string, where ℓ is far from quadratic in v⃗), the
    momentum is reached by continuation from p⃗ = 0 in 32 stages.  A ``start`` ``[..., 3]``
    inside the light cone (a nearby solution: the previous call's) is tried first; the root is
    the same (p⃗(v⃗) is the gradient of a strictly convex ℓ where the law is causal), only the
    number of iterations changes.

    Raises
    ------
    ValueError
        When Newton's method does not converge (no subluminal velocity has that momentum, or
        the Hessian of ℓ is singular there).
    """
    p = np.asarray(p, dtype=float)
    x = np.asarray(x, dtype=float)
    if start is not None and np.shape(start) == p.shape and np.all(np.linalg.norm(start, axis=-1) < c):
        out = _newton(p, x, np.array(start, dtype=float), law, c, iterations)
        if out is not None:
            return out
    v = p * (c * c / law[0](np.linalg.norm(x, axis=-1)))[..., None]
    speed = np.linalg.norm(v, axis=-1, keepdims=True)
    v = np.where(speed >= 0.9 * c, v * (0.9 * c / np.maximum(speed, 1e-300)), v)
    out = _newton(p, x, v, law, c, iterations)
    if out is not None:
        return out
    v = np.zeros_like(p)
    for s in np.linspace(0.0, 1.0, 33)[1:]:
        v = _newton(s * p, x, v, law, c, iterations)
        if v is None:
            raise ValueError("the momentum has no subluminal velocity, or the Hessian of ℓ is singular there "
                             "(Newton's method for v(p, x′) did not converge)")
    return v
