"""Quick-look figures of a run (``cartan plot``).

:func:`plot_run` draws, side by side, snapshots of the configuration coloured by time
(the centreline ``position`` for affine groups, in 3-D or 2-D; the ``field`` when it is a
point of R² or R³; nothing otherwise) and the energies against time: kinetic, potential,
total ``E = K + V``, and ``E + D − W`` (total plus dissipated energy minus external work,
constant when the energy balance closes).  Given a static equilibrium or a continuation
path it hands over to :func:`plot_static` (the equilibrium shape, its displacement and the
Newton residuals) or :func:`plot_continuation` (the load–displacement chart of
:func:`plot_load_displacement`, bifurcations and folds marked, branches coloured, beside
shapes along the path).  3-D curves lying in a coordinate plane are drawn in that plane.
A surface (d = 2 in space) is drawn in 3D coloured by a node field; a solid (d = 3) as the
outer faces of its deformed lattice, optionally with a coordinate slice through it.  Periodic
axes are drawn closed (:func:`_close_seams`): one more layer of nodes, the first moved by the
axis's holonomy recorded in the run configuration, so that a tube, a periodic strip or a closed
rod has no gap at its seam.  A medium
may draw its own picture instead: :func:`plot_run` first calls the ``draw(ds, fig)``
classmethod of the medium that wrote the file (:meth:`cartan.medium.Medium.draw`), found by
the name the file records (:func:`medium_name`).
matplotlib is used through its object API with the Agg canvas, so no display is needed.
"""

from __future__ import annotations

import os
import pathlib
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:  # pragma: no cover
    import xarray as xr
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

__all__ = ["medium_name", "plot_continuation", "plot_load_displacement", "plot_run", "plot_static", "result_kind"]


def _points(ds: xr.Dataset) -> np.ndarray | None:
    """Configuration points ``[time, nodes..., k]`` (k = 2 or 3), or None."""
    for name in ("position", "field"):
        if name in ds:
            arr = np.asarray(ds[name].values)
            if arr.ndim >= 3 and arr.shape[-1] in (2, 3):
                return arr
    return None


def _snapshot_indices(nt: int, snapshots: int) -> np.ndarray:
    if nt <= snapshots:
        return np.arange(nt)
    return np.unique(np.linspace(0, nt - 1, snapshots).round().astype(int))


def _draw_configuration(fig: Figure, ax_slot: int, ds: xr.Dataset, pts: np.ndarray, snapshots: int) -> None:
    from matplotlib import cm, colors

    t = np.asarray(ds["time"].values, dtype=float)
    k = pts.shape[-1]
    norm = colors.Normalize(vmin=float(t[0]), vmax=float(t[-1]) if t[-1] > t[0] else float(t[0]) + 1.0)
    cmap = cm.viridis
    ax = fig.add_subplot(1, 2, ax_slot, projection="3d" if k == 3 else None)
    curve = pts.ndim == 3  # d = 1: [time, node, k]
    for i in _snapshot_indices(len(t), snapshots):
        p = _closed(ds, pts[i])[0] if curve else pts[i].reshape(-1, k)  # a closed rod drawn closed
        c = cmap(norm(t[i]))
        if curve:
            ax.plot(*p.T, color=c, lw=1.5)
        else:
            ax.scatter(*p.T, color=c, s=4)
    if k == 3:  # equal scales: a cube around the data
        _cube(ax, pts.reshape(-1, k))
    else:
        ax.set_aspect("equal", adjustable="datalim")
        ax.set_xlabel("x")
        ax.set_ylabel("y")
    ax.set_title("configuration" + (" (centreline)" if curve else ""))
    sm = cm.ScalarMappable(norm=norm, cmap=cmap)
    sm.set_array([])
    fig.colorbar(sm, ax=ax, shrink=0.7, pad=0.1, label="time")


def _node_dims(ds: xr.Dataset) -> tuple[str, ...]:
    """Names of the node dimensions of the configuration variable (``("u", "v")`` for a surface)."""
    for name in ("position", "field"):
        if name in ds and ds[name].ndim >= 3 and ds[name].shape[-1] in (2, 3):
            return tuple(ds[name].dims[1:-1])
    return ()


def _node_field_dims(var: xr.DataArray, dims: tuple[str, ...]) -> tuple[str, ...] | None:
    """The dimensions of ``var`` beyond ``time`` and the node dimensions ``dims`` (``()`` for a
    scalar node field, ``("row", "col")`` for a tensor per node), or None if ``var`` is not a
    node field."""
    rest = var.dims[1:] if var.dims[:1] == ("time",) else var.dims
    if not dims or rest[: len(dims)] != dims:
        return None
    return tuple(rest[len(dims):])


def _dim_labels(ds: xr.Dataset, dim: str) -> list[str]:
    """The labels of dimension ``dim``: its coordinate's values as text, else the indices."""
    if dim in ds.coords and ds[dim].dims == (dim,):
        return [str(v) for v in ds[dim].values]
    return [str(k) for k in range(ds.sizes[dim])]


def _components_text(ds: xr.Dataset, extra: tuple[str, ...]) -> str:
    return "; ".join(f"{dim}: {', '.join(_dim_labels(ds, dim))}" for dim in extra)


def _select_component(ds: xr.Dataset, field: str, dims: tuple[str, ...]) -> tuple[xr.DataArray, str]:
    """The node variable named by ``field``: ``NAME`` for a scalar per node, or
    ``NAME[a,b]`` (``NAME[row=a,col=b]``) for one component of a variable with extra
    dimensions beyond the nodes, the labels in the order of those dimensions (their indices
    0, 1, … for a dimension without labels).  Returns the variable and its display name.

    Raises
    ------
    ValueError
        A variable not in the file (the node fields are listed), a variable with extra
        dimensions and no component (the dimensions and their labels are named), or a
        component that does not match the dimensions or their labels.
    """
    import re

    match = re.fullmatch(r"\s*([^\[\]]+?)\s*(?:\[([^\[\]]*)\])?\s*", str(field))
    name = match.group(1) if match else str(field)
    spec = match.group(2) if match else None
    if name not in ds.data_vars:
        choices = []
        for v in sorted(ds.data_vars):
            extra = _node_field_dims(ds[v], dims)
            if extra is not None:
                choices.append(f"{v}[{','.join(extra)}]" if extra else str(v))
        raise ValueError(f"field {name!r} is not in the file; node fields: {', '.join(choices) or 'none'}")
    var = ds[name]
    extra = _node_field_dims(var, dims) or ()
    if spec is None:
        if extra:
            example = ",".join(_dim_labels(ds, d)[0] for d in extra)
            raise ValueError(f"field {name!r} has the dimensions {', '.join(extra)} beyond the nodes "
                             f"({_components_text(ds, extra)}): choose a component, e.g. {name}[{example}]")
        return var, name
    items = [item.strip() for item in spec.split(",")]
    if not extra:
        raise ValueError(f"field {name!r} has no dimension beyond the nodes to choose a component {spec!r} of")
    if len(items) != len(extra):
        raise ValueError(f"field {name!r}[{spec}]: give {len(extra)} label(s), one per dimension "
                         f"{', '.join(extra)} ({_components_text(ds, extra)})")
    chosen: dict[str, int] = {}
    keyed = [item.partition("=") for item in items]
    if all(sep for _, sep, _ in keyed):
        pairs = [(d.strip(), lab.strip()) for d, _, lab in keyed]
        unknown = [d for d, _ in pairs if d not in extra]
        if unknown or len({d for d, _ in pairs}) != len(pairs):
            raise ValueError(f"field {name!r}[{spec}]: name each of the dimensions {', '.join(extra)} once")
    elif any(sep for _, sep, _ in keyed):
        raise ValueError(f"field {name!r}[{spec}]: give all labels by position or all as DIM=LABEL")
    else:
        pairs = list(zip(extra, items, strict=True))
    for dim, label in pairs:
        labels = _dim_labels(ds, dim)
        if label not in labels:
            raise ValueError(f"field {name!r}[{spec}]: {label!r} is not a label of {dim!r} ({', '.join(labels)})")
        chosen[dim] = labels.index(label)
    text = ",".join(_dim_labels(ds, d)[chosen[d]] for d in extra)
    return var.isel(chosen), f"{name}[{text}]"


def _node_values(ds: xr.Dataset, pts: np.ndarray, field: str | None, index: int) -> tuple[np.ndarray, str]:
    """The nodal values ``[*nodes]`` (``[n_u, n_v]`` for a surface, ``[n_u, n_v, n_w]`` for a
    solid) a configuration ``pts [time, *nodes, 3]`` is coloured by at snapshot ``index``: the
    variable ``field`` of the Dataset (a scalar per node, or ``NAME[a,b]`` for one component
    of a variable with extra dimensions, :func:`_select_component`), else the displacement
    from the first snapshot (its norm); and the colour bar's label (long name and units)."""
    nodes = pts.shape[1:-1]
    if field is not None:
        dims = _node_dims(ds)
        var, shown = _select_component(ds, field, dims)
        values = np.asarray(var.values, dtype=float)
        if values.shape[-len(nodes):] != nodes or values.ndim not in (len(nodes), len(nodes) + 1):
            raise ValueError(f"field {shown!r} is not one value per node (shape {values.shape}, nodes {nodes})")
        values = values[index] if values.ndim == len(nodes) + 1 else values
        label = _axis_label(var, shown)
        if "[" in shown or len(label) > 40:  # a component, or a long name: the name and the units
            label = _axis_label(var.copy(deep=False).assign_attrs(long_name=shown), shown)
        return values, label
    units = str(ds["position"].attrs.get("units", "")) if "position" in ds else ""
    return np.linalg.norm(pts[index] - pts[0], axis=-1), "|displacement|" + (f" [{units}]" if units else "")


# ---------------------------------------------------------------------------- periodic seams
def _seams(ds: xr.Dataset) -> tuple[tuple[bool, ...], dict[int, np.ndarray]]:
    """The periodic flags of the node axes and the holonomies ``{axis: H}`` of the problem that
    wrote ``ds`` (``problem.grid.periodic`` and ``problem.holonomy`` of ``cartan_config``, the
    latter ``(m, m)`` group elements with Φ(u_α + L_α) = H_α Φ(u_α)); ``((), {})`` when the file
    records no grid."""
    import json

    try:
        config = json.loads(str(ds.attrs.get("cartan_config", "")))
    except ValueError:
        return (), {}
    problem = config.get("problem", {}) if isinstance(config, dict) else {}
    grid = problem.get("grid", {}) if isinstance(problem, dict) else {}
    periodic = grid.get("periodic") if isinstance(grid, dict) else None
    if not isinstance(periodic, list) or not all(isinstance(p, bool) for p in periodic):
        return (), {}
    holonomy: dict[int, np.ndarray] = {}
    recorded = problem.get("holonomy")
    for axis, H in (recorded.items() if isinstance(recorded, dict) else ()):
        try:
            holonomy[int(axis)] = np.asarray(H, dtype=float)
        except (TypeError, ValueError):
            continue
    return tuple(periodic), holonomy


def _glued(ds: xr.Dataset) -> tuple[int | None, ...] | None:
    """The glued axes of the grid of the run that wrote ``ds`` (``problem.grid.glued`` of
    ``cartan_config``: per axis the periodic axis its ends are glued across, or None); None when
    the file records none."""
    import json

    try:
        config = json.loads(str(ds.attrs.get("cartan_config", "")))
        glued = config["problem"]["grid"]["glued"]
    except (ValueError, KeyError, TypeError):
        return None
    if not isinstance(glued, list) or not all(isinstance(b, int) for b in glued):
        return None
    return tuple(None if b < 0 else b for b in glued)


def _close_poles(points: np.ndarray, values: np.ndarray | None,
                 glued: tuple[int | None, ...] | None) -> tuple[np.ndarray, np.ndarray | None]:
    """Points ``[*nodes, k]`` (and ``values`` ``[*nodes]``) with, on each glued axis α (a chart
    closed over poles, :class:`~cartan.grid.Grid` ``glued``), one layer before the first and one
    after the last: the pole each end closes on, drawn at the mean of the end's ring of nodes
    (values: the ring's mean), so that a sphere is drawn without holes at its poles."""
    for axis, beta in enumerate(glued or ()):
        if beta is None or axis >= points.ndim - 1:
            continue
        n = points.shape[axis]
        rings = [np.take(points, [i], axis=axis) for i in (0, n - 1)]
        caps = [np.broadcast_to(np.mean(r, axis=beta, keepdims=True), r.shape) for r in rings]
        points = np.concatenate([caps[0], points, caps[1]], axis=axis)
        if values is not None:
            vr = [np.take(values, [i], axis=axis) for i in (0, n - 1)]
            vc = [np.broadcast_to(np.mean(r, axis=beta, keepdims=True), r.shape) for r in vr]
            values = np.concatenate([vc[0], values, vc[1]], axis=axis)
    return points, values


def _close_seams(points: np.ndarray, values: np.ndarray | None, periodic: tuple[bool, ...],
                 holonomy: dict[int, np.ndarray], affine: bool = True) -> tuple[np.ndarray, np.ndarray | None]:
    """Points ``[*nodes, k]`` (and nodal ``values`` ``[*nodes]``) with one more layer of nodes
    on each periodic axis α: the image of the first layer under the axis's holonomy,
    x(u_α + L_α) = R_H x(u_α) + t_H (H = [[1, 0], [t_H, R_H]], the identity for a closed axis),
    so that a tube, a ring or a periodic strip is drawn without a gap between its last and
    first nodes (the values repeat the first layer's).

    An axis is left open when its holonomy does not act on the points (``affine`` False: the
    points are not positions, or H is not ``(k + 1, k + 1)``), or when, with no holonomy
    recorded, the first layer is not next to the last one (a gap longer than 1.5 times the
    longest step between neighbours along the axis: an open chart whose holonomy the file does not
    hold, e.g. one written before the holonomy was recorded).
    """
    nodes = points.shape[:-1]
    k = points.shape[-1]
    for axis, is_periodic in enumerate(periodic[: len(nodes)]):
        n = points.shape[axis]
        if not is_periodic or n < 2:
            continue
        first = np.take(points, [0], axis=axis)
        H = holonomy.get(axis)
        if H is not None:
            if not affine or H.shape != (k + 1, k + 1):
                continue
            wrap = first @ H[1:, 1:].T + H[1:, 0]
        else:
            steps = np.linalg.norm(np.diff(points, axis=axis), axis=-1)
            gap = np.linalg.norm(np.take(points, [-1], axis=axis) - first, axis=-1)
            if np.nanmax(gap) > 1.5 * max(float(np.nanmax(steps)), 1e-300):
                continue
            wrap = first
        points = np.concatenate([points, wrap], axis=axis)
        if values is not None:
            values = np.concatenate([values, np.take(values, [0], axis=axis)], axis=axis)
    return points, values


def _closed(ds: xr.Dataset, points: np.ndarray,
            values: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray | None]:
    """:func:`_close_seams` with the periodic axes and holonomies of the run that wrote ``ds``
    (points ``[*nodes, k]``: positions when the file holds ``position``), after the poles of
    its glued axes (:func:`_close_poles`)."""
    periodic, holonomy = _seams(ds)
    if not periodic or len(periodic) != points.ndim - 1:
        return points, values
    if "position" in ds:  # a chart closed over poles (the sphere): its caps, then its seam
        points, values = _close_poles(points, values, _glued(ds))
    return _close_seams(points, values, periodic, holonomy, affine="position" in ds)


def _draw_surface(ax: Axes, surface: np.ndarray, values: np.ndarray, norm, cmap, alpha: float = 1.0) -> None:
    """A deformed surface ``[n_u, n_v, 3]`` as faces coloured by nodal ``values`` ``[n_u, n_v]``
    (each face takes the mean of its four corners)."""
    corners = 0.25 * (values[:-1, :-1] + values[1:, :-1] + values[:-1, 1:] + values[1:, 1:])
    ax.plot_surface(surface[..., 0], surface[..., 1], surface[..., 2], facecolors=cmap(norm(corners)),
                    rstride=1, cstride=1, linewidth=0.2, edgecolor="0.3", antialiased=True, shade=False, alpha=alpha)


def _cube(ax: Axes, flat: np.ndarray) -> None:
    """Equal scales on a 3D axes: a cube around the points ``[N, 3]``."""
    lo, hi = np.nanmin(flat, axis=0), np.nanmax(flat, axis=0)
    centre = 0.5 * (lo + hi)
    half = 0.55 * max(float(np.max(hi - lo)), 1e-12)
    ax.set_xlim(centre[0] - half, centre[0] + half)
    ax.set_ylim(centre[1] - half, centre[1] + half)
    ax.set_zlim(centre[2] - half, centre[2] + half)
    ax.set_box_aspect((1.0, 1.0, 1.0))
    ax.set_xlabel("x")
    ax.set_ylabel("y")
    ax.set_zlabel("z")


def _draw_surface_panel(fig: Figure, slot: tuple[int, int, int], ds: xr.Dataset, pts: np.ndarray, field: str | None,
                        title: str) -> None:
    """The last configuration of a surface (d = 2 in space, ``pts [time, n_u, n_v, 3]``) in 3D,
    coloured by ``field``, the first one as a grey wireframe."""
    from matplotlib import cm, colors

    ax = fig.add_subplot(*slot, projection="3d")
    values, label = _node_values(ds, pts, field, -1)
    lo, hi = float(np.nanmin(values)), float(np.nanmax(values))
    norm = colors.Normalize(vmin=lo, vmax=hi if hi > lo else lo + 1.0)
    cmap = cm.viridis
    last, values = _closed(ds, pts[-1], values)
    shown = [last]
    if pts.shape[0] > 1:
        first, _ = _closed(ds, pts[0])
        ax.plot_wireframe(first[..., 0], first[..., 1], first[..., 2], color="0.6", linewidth=0.4)
        shown.append(first)
    _draw_surface(ax, last, values, norm, cmap)
    _cube(ax, np.concatenate([p.reshape(-1, 3) for p in shown]))
    ax.set_title(title)
    sm = cm.ScalarMappable(norm=norm, cmap=cmap)
    sm.set_array([])
    fig.colorbar(sm, ax=ax, shrink=0.7, pad=0.1, label=label)


def _is_surface(pts: np.ndarray | None) -> bool:
    """Points ``[time, n_u, n_v, 3]`` of a surface in space (d = 2), with at least 2 × 2 nodes."""
    return pts is not None and pts.ndim == 4 and pts.shape[-1] == 3 and min(pts.shape[1:3]) >= 2


def _is_solid(pts: np.ndarray | None) -> bool:
    """Points ``[time, n_u, n_v, n_w, 3]`` of a solid (d = 3), with at least 2 × 2 × 2 nodes."""
    return pts is not None and pts.ndim == 5 and pts.shape[-1] == 3 and min(pts.shape[1:4]) >= 2


def _parse_slice(spec: str, ds: xr.Dataset, pts: np.ndarray | None) -> tuple[int, int]:
    """``(axis, node index)`` of a slice ``"u"``, ``"v"``, ``"w"`` (the middle node) or
    ``"AXIS=INDEX"`` through a solid ``pts [time, n_u, n_v, n_w, 3]``.

    Raises
    ------
    ValueError
        If the result is not a solid, the axis is not one of its node dimensions, or the index
        is not in ``0 ≤ INDEX < n``.
    """
    if not _is_solid(pts):
        d = ds["position"].ndim - 2 if "position" in ds else (0 if pts is None else pts.ndim - 2)
        raise ValueError(f"slice {spec!r}: only a solid (a d = 3 medium) can be sliced; this result has d = {d}")
    dims = _node_dims(ds) or ("u", "v", "w")
    name, sep, index_text = str(spec).partition("=")
    name = name.strip()
    if name not in dims:
        raise ValueError(f"slice {spec!r}: choose an axis {', '.join(dims)}, optionally with a node index "
                         f"({dims[0]}=INDEX)")
    axis = dims.index(name)
    n = pts.shape[1 + axis]
    if not sep:
        return axis, n // 2
    try:
        index = int(index_text)
    except ValueError:
        raise ValueError(f"slice {spec!r}: the node index must be an integer, 0 ≤ INDEX ≤ {n - 1}") from None
    if not 0 <= index < n:
        raise ValueError(f"slice {spec!r}: node index out of range, 0 ≤ INDEX ≤ {n - 1}")
    return axis, index


def _faces(block: np.ndarray) -> list[np.ndarray]:
    """The six outer faces of a node array ``[n_u, n_v, n_w, ...]`` (u = 0, u = end, v = 0, ...),
    each ``[n_a, n_b, ...]``."""
    return [block[0], block[-1], block[:, 0], block[:, -1], block[:, :, 0], block[:, :, -1]]


def _edges(block: np.ndarray) -> list[np.ndarray]:
    """The twelve edges ``[n, 3]`` of a block of points ``[n_u, n_v, n_w, 3]``."""
    out = []
    for i in (0, -1):
        for j in (0, -1):
            out += [block[:, i, j], block[i, :, j], block[i, j, :]]
    return out


def _draw_block(ax: Axes, block: np.ndarray, values: np.ndarray, norm, cmap,
                inner: tuple[int, ...] = ()) -> None:
    """The outer faces of a deformed solid ``[n_u, n_v, n_w, 3]`` as quadrilaterals coloured by
    the nodal ``values`` ``[n_u, n_v, n_w]`` (the mean of each face's four corners), in one
    collection so that the faces of all six sides are depth-sorted together; the two faces
    normal to each axis in ``inner`` (a periodic axis, closed by :func:`_close_seams`) are
    inside the body and left out."""
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    quads, colours = [], []
    for side, (surface, vals) in enumerate(zip(_faces(block), _faces(values))):
        if side // 2 in inner:
            continue
        corners = np.stack([surface[:-1, :-1], surface[1:, :-1], surface[1:, 1:], surface[:-1, 1:]], axis=-2)
        quads.append(corners.reshape(-1, 4, 3))
        colours.append((0.25 * (vals[:-1, :-1] + vals[1:, :-1] + vals[:-1, 1:] + vals[1:, 1:])).ravel())
    poly = Poly3DCollection(np.concatenate(quads), facecolors=cmap(norm(np.concatenate(colours))),
                            edgecolors="0.3", linewidths=0.2)
    ax.add_collection3d(poly)


def _draw_solid_panels(fig: Figure, slots: list[tuple[int, int, int]], ds: xr.Dataset, pts: np.ndarray,
                       field: str | None, title: str, cut: tuple[int, int] | None) -> None:
    """The last configuration of a solid (d = 3, ``pts [time, n_u, n_v, n_w, 3]``) in 3D: its
    outer faces coloured by ``field``, the edges of the first one dashed grey; and, given
    ``cut = (axis, index)``, the material slice at that node index in a second panel, drawn
    deformed and coloured on the same scale inside the edges of the deformed block."""
    from matplotlib import cm, colors

    values, label = _node_values(ds, pts, field, -1)
    lo, hi = float(np.nanmin(values)), float(np.nanmax(values))
    norm = colors.Normalize(vmin=lo, vmax=hi if hi > lo else lo + 1.0)
    cmap = cm.viridis
    last, values = _closed(ds, pts[-1], values)
    inner = tuple(a for a in range(3) if last.shape[a] > pts.shape[1 + a])  # the closed periodic axes
    ax = fig.add_subplot(*slots[0], projection="3d")
    shown = [last]
    if pts.shape[0] > 1:
        first, _ = _closed(ds, pts[0])
        for e in _edges(first):
            ax.plot(*e.T, "--", color="0.55", lw=0.8)
        shown.append(first)
    _draw_block(ax, last, values, norm, cmap, inner)
    _cube(ax, np.concatenate([p.reshape(-1, 3) for p in shown]))
    ax.set_title(title)
    sm = cm.ScalarMappable(norm=norm, cmap=cmap)
    sm.set_array([])
    fig.colorbar(sm, ax=ax, shrink=0.7, pad=0.1, label=label)
    if cut is None:
        return
    axis, index = cut
    dims = _node_dims(ds) or ("u", "v", "w")
    ax = fig.add_subplot(*slots[1], projection="3d")
    for e in _edges(last):
        ax.plot(*e.T, color="0.45", lw=0.8)
    _draw_surface(ax, np.take(last, index, axis=axis), np.take(values, index, axis=axis), norm, cmap)
    _cube(ax, last.reshape(-1, 3))
    where = f"{dims[axis]} node {index}"
    if dims[axis] in ds.coords and ds[dims[axis]].size == pts.shape[1 + axis]:
        where = f"{dims[axis]} = {float(ds[dims[axis]].values[index]):.4g} (node {index})"
    ax.set_title(f"slice {where}")
    fig.colorbar(sm, ax=ax, shrink=0.7, pad=0.1, label=label)


def _draw_energies(fig: Figure, ax_slot: int, ncols: int, ds: xr.Dataset) -> None:
    ax = fig.add_subplot(1, ncols, ax_slot)
    t = np.asarray(ds["time"].values, dtype=float)
    K = np.asarray(ds["kinetic_energy"].values)
    V = np.asarray(ds["potential_energy"].values)
    D = np.asarray(ds["dissipated_energy"].values) if "dissipated_energy" in ds else np.zeros_like(K)
    W = np.asarray(ds["external_work"].values) if "external_work" in ds else np.zeros_like(K)
    E = K + V
    ax.plot(t, K, label="kinetic K")
    ax.plot(t, V, label="potential V")
    ax.plot(t, E, label="total E = K + V", lw=2)
    label = "E + D − W (balance)" if np.any(W) else "E + D (dissipated + total)"
    ax.plot(t, E + D - W, "--", label=label, color="k")
    ax.set_xlabel("time")
    ax.set_ylabel("energy")
    ax.set_title("energies")
    ax.legend(fontsize="small")
    ax.grid(True, alpha=0.3)


def medium_name(ds: xr.Dataset) -> str | None:
    """The registry name of the medium that wrote ``ds``.

    Read from ``problem.medium`` of the JSON ``cartan_config`` attribute, else from the
    ``medium 'NAME'`` part of the ``source`` attribute (both written by the core).

    Parameters
    ----------
    ds : xarray.Dataset
        A result of :func:`cartan.simulate`, :func:`cartan.solve_static` or a run file.

    Returns
    -------
    str or None
        The name (e.g. ``"cosserat-rod"``), or None when the Dataset names no medium.
    """
    import json
    import re

    try:
        config = json.loads(str(ds.attrs.get("cartan_config", "")))
    except ValueError:
        config = None
    name = config.get("problem", {}).get("medium") if isinstance(config, dict) else None
    if isinstance(name, str) and name:
        return name
    match = re.search(r"medium '([^']+)'", str(ds.attrs.get("source", "")))
    return match.group(1) if match else None


def _medium_picture(ds: xr.Dataset, fig: Figure) -> bool:
    """Let the medium that wrote ``ds`` draw into ``fig`` (:meth:`cartan.medium.Medium.draw`);
    False when the medium is not named, not registered, or draws nothing."""
    from .plugins import RegistryError, get_registry

    name = medium_name(ds)
    if name is None:
        return False
    try:
        medium = get_registry().get("media", name)
    except RegistryError:  # a file of a medium whose plugin is not installed here
        return False
    draw = getattr(medium, "draw", None)
    return bool(draw(ds, fig)) if callable(draw) else False


def _save(fig: Figure, path: str | os.PathLike | None) -> None:
    if path is not None:
        fig.savefig(pathlib.Path(path), dpi=120)


def plot_run(
    ds: xr.Dataset, path: str | os.PathLike | None = None, snapshots: int = 8, title: str | None = None,
    field: str | None = None, slice: str | None = None, generic: bool = False,
) -> Figure:
    """Quick-look figure of a run: configuration snapshots and energies against time.

    The medium that wrote the Dataset (:func:`medium_name`) is asked first: when its class
    draws a picture of its own (:meth:`cartan.medium.Medium.draw` returns True) that picture
    is the figure.  Otherwise static equilibria go to :func:`plot_static`, continuation paths
    to :func:`plot_continuation` (see :func:`result_kind`), and a dynamic run is drawn here.

    Parameters
    ----------
    ds : xarray.Dataset
        A run Dataset (from :func:`cartan.simulate` or :func:`cartan.open`).
    path : path-like, optional
        Where to save the figure (format from the suffix, e.g. ``.png``, ``.pdf``).
    snapshots : int
        Number of configurations drawn, evenly spaced in time (along the path for a
        continuation result).
    title : str, optional
        Figure title (default: the Dataset's ``title`` attribute).
    field : str, optional
        For a surface (a d = 2 medium in space: shells, plates, membranes) or a solid (d = 3),
        the node variable its deformed configuration is coloured by (default: the
        displacement's norm).  A surface is drawn in 3D, the initial one as a wireframe; a
        solid as the outer faces of its deformed lattice, the edges of the initial block dashed.
        A variable with dimensions beyond the nodes (a tensor per node, say ``(row, col)``) is
        given with one component: ``"NAME[x,u]"`` (labels in the order of those dimensions,
        indices for a dimension without labels) or ``"NAME[row=x,col=u]"``.
    slice : str, optional
        For a solid, also draw the material slice ``"u"``, ``"v"`` or ``"w"`` through the
        middle node (``"u=INDEX"`` for another node index), deformed and coloured by ``field``.
    generic : bool
        Draw the generic picture even when the medium has its own.  Giving ``field`` or
        ``slice`` asks for the generic picture too.

    Returns
    -------
    matplotlib.figure.Figure

    Raises
    ------
    ValueError
        If ``field`` is not a node variable of the file, has dimensions beyond the nodes and no
        component (the message names the dimensions and their labels), or ``slice`` names no
        node plane of a solid (or the result is not a solid).
    """
    from matplotlib.figure import Figure

    if not generic and field is None and slice is None:
        fig = Figure(figsize=(12.0, 4.8), layout="constrained")
        if _medium_picture(ds, fig):
            if not fig.get_suptitle():
                fig.suptitle(title if title is not None else str(ds.attrs.get("title", "")))
            _save(fig, path)
            return fig
    kind = result_kind(ds)
    if kind == "continuation":
        if slice is not None:
            raise ValueError(f"slice {slice!r}: a continuation result has no solid to slice")
        return plot_continuation(ds, path, snapshots=snapshots, title=title)
    if kind == "static":
        return plot_static(ds, path, title=title, field=field, slice=slice)

    pts = _points(ds)
    cut = _parse_slice(slice, ds, pts) if slice is not None else None
    ncols = 2 if pts is not None and ds.sizes.get("time", 0) > 0 else 1
    ncols += cut is not None
    fig = Figure(figsize=(6.0 * ncols, 4.8), layout="constrained")
    when = f"t = {float(ds['time'].values[-1]):.4g}" if ds.sizes.get("time", 0) else ""
    if ncols >= 2 and _is_solid(pts):
        _draw_solid_panels(fig, [(1, ncols, 1), (1, ncols, 2)], ds, pts, field, when, cut)
    elif ncols == 2 and _is_surface(pts):
        _draw_surface_panel(fig, (1, 2, 1), ds, pts, field, when)
    elif ncols == 2:
        _draw_configuration(fig, 1, ds, pts, snapshots)
    _draw_energies(fig, ncols, ncols, ds)
    fig.suptitle(title if title is not None else str(ds.attrs.get("title", "")))
    _save(fig, path)
    return fig


# ---------------------------------------------------------------------------- static and continuation results
def result_kind(ds: xr.Dataset) -> str:
    """``"continuation"`` (a path along ``path``), ``"static"`` (a Newton equilibrium) or ``"dynamic"``."""
    if "path" in ds.dims and "load_factor" in ds:
        return "continuation"
    if "newton_residual" in ds:
        return "static"
    return "dynamic"


def _in_plane(curves: list[np.ndarray]) -> tuple[list[int], list[str]]:
    """The spatial axes to draw: all of them, or the two that vary when 3-D curves lie in a
    coordinate plane (e.g. a rod bending in x–z)."""
    k = curves[0].shape[-1]
    labels = ["x", "y", "z"][:k] if k <= 3 else [f"x{i}" for i in range(k)]
    if k != 3:
        return list(range(k)), labels
    flat = np.concatenate([c.reshape(-1, k) for c in curves])
    spread = np.nanmax(flat, axis=0) - np.nanmin(flat, axis=0)
    flat_axes = np.nonzero(spread <= 1e-9 * max(float(np.max(spread)), 1e-300))[0]
    if flat_axes.size:
        keep = [i for i in range(3) if i != int(flat_axes[0])]
        return keep, [labels[i] for i in keep]
    return [0, 1, 2], labels


def _node_lines(surface: np.ndarray) -> list[np.ndarray]:
    """The node lines ``[n, k]`` of a surface ``[n_u, n_v, k]``: along u (one per v), then along v."""
    return [*np.moveaxis(surface, 1, 0), *surface]


def _draw_shapes(fig: Figure, slot: tuple[int, int, int], curves: list[np.ndarray], values: np.ndarray | None,
                 label: str, reference: np.ndarray | None = None, title: str = "shape",
                 ds: xr.Dataset | None = None) -> None:
    """Curves ``[nodes, k]`` (for a surface ``[nu, nv, k]``, its lines along u and v; a scatter
    for d ≥ 3 arrays) coloured by ``values``, the reference configuration dashed; given the
    Dataset ``ds`` they wrote, a closed rod's or a tube's node lines run across its periodic
    seams (:func:`_closed`)."""
    from matplotlib import cm, colors

    if ds is not None:
        curves = [_closed(ds, c)[0] if c.ndim <= 3 else c for c in curves]
        if reference is not None and reference.ndim <= 3:
            reference = _closed(ds, reference)[0]
    every = curves + ([reference] if reference is not None else [])
    axes, names = _in_plane(every)
    three_d = len(axes) == 3
    ax = fig.add_subplot(*slot, projection="3d" if three_d else None)
    cmap = cm.viridis
    norm = None
    if values is not None and len(values):
        lo, hi = float(np.min(values)), float(np.max(values))
        norm = colors.Normalize(vmin=lo, vmax=hi if hi > lo else lo + 1.0)
    if reference is not None:
        ref = reference.reshape(-1, reference.shape[-1])[:, axes]
        if reference.ndim == 2:
            ax.plot(*ref.T, "--", color="0.6", lw=1.0, label="initial")
        elif reference.ndim == 3:  # a surface: its lines along u and v
            for k, line in enumerate(_node_lines(reference)):
                ax.plot(*line[:, axes].T, "--", color="0.6", lw=0.8, label="initial" if k == 0 else None)
        else:
            ax.scatter(*ref.T, color="0.6", s=2, label="initial")
    for i, c in enumerate(curves):
        colour = cmap(norm(values[i])) if norm is not None else "C0"
        pts = c.reshape(-1, c.shape[-1])[:, axes]
        if c.ndim == 2:
            ax.plot(*pts.T, color=colour, lw=1.5)
        elif c.ndim == 3:
            for line in _node_lines(c):
                ax.plot(*line[:, axes].T, color=colour, lw=1.0)
        else:
            ax.scatter(*pts.T, color=colour, s=4)
    if three_d:
        _cube(ax, np.concatenate([c.reshape(-1, c.shape[-1])[:, axes] for c in every]))
        ax.set_zlabel(names[2])
    else:
        ax.set_aspect("equal", adjustable="datalim")
        ax.grid(True, alpha=0.3)
    ax.set_xlabel(names[0])
    ax.set_ylabel(names[1])
    ax.set_title(title)
    if reference is not None:
        ax.legend(fontsize="small", loc="best")
    if norm is not None and len(curves) > 1:
        sm = cm.ScalarMappable(norm=norm, cmap=cmap)
        sm.set_array([])
        fig.colorbar(sm, ax=ax, shrink=0.7, pad=0.1, label=label)


def _axis_label(var: xr.DataArray, fallback: str) -> str:
    text = str(var.attrs.get("long_name", fallback))
    units = var.attrs.get("units")
    return f"{text} [{units}]" if units and units != "1" else text


def plot_load_displacement(
    ds: xr.Dataset,
    path: str | os.PathLike | None = None,
    *,
    ax: Axes | None = None,
    title: str | None = None,
) -> Figure:
    """Load–displacement chart of a continuation result: λ against the recorded displacement.

    The path is drawn per branch (``branch`` 0: the primary path, 1: the branch followed
    after the switch at the first bifurcation, starting at the critical point); critical
    points are marked (bifurcation ★, fold ◆) and labelled with their load factor.

    Parameters
    ----------
    ds : xarray.Dataset
        A continuation result (:func:`cartan.continuation.continuation`, or a file of
        ``cartan run`` on a ``mode = "continuation"`` scene): ``load_factor`` and ``monitor``
        along ``path``; ``branch``, ``critical_load``, ``critical_monitor``,
        ``critical_kind`` and ``critical_path_index`` are used when present.
    path : path-like, optional
        Where to save the figure (format from the suffix).
    ax : matplotlib.axes.Axes, optional
        Draw into these axes (the figure is then ``ax.figure``) instead of a new figure.
    title : str, optional
        Axes title (default: "load–displacement").

    Returns
    -------
    matplotlib.figure.Figure

    Raises
    ------
    ValueError
        If ``ds`` is not a continuation result.
    """
    from matplotlib.figure import Figure

    if result_kind(ds) != "continuation" or "monitor" not in ds:
        raise ValueError("ds: not a continuation result (needs load_factor and monitor along path)")
    if ax is None:
        fig = Figure(figsize=(6.0, 4.8), layout="constrained")
        ax = fig.add_subplot(1, 1, 1)
    else:
        fig = ax.figure
    lam = np.asarray(ds["load_factor"].values, dtype=float)
    w = np.asarray(ds["monitor"].values, dtype=float)
    branch = np.asarray(ds["branch"].values) if "branch" in ds else np.zeros(lam.size, dtype=int)
    kinds = [str(k) for k in ds["critical_kind"].values] if "critical_kind" in ds else []
    c_lam = np.asarray(ds["critical_load"].values, dtype=float) if kinds else np.zeros(0)
    c_w = np.asarray(ds["critical_monitor"].values, dtype=float) if kinds else np.zeros(0)
    c_idx = np.asarray(ds["critical_path_index"].values) if kinds and "critical_path_index" in ds else None
    names = {0: "primary path", 1: "after the branch switch"}
    for b in np.unique(branch):
        sel = np.nonzero(branch == b)[0]
        x, y = w[sel], lam[sel]
        if b > 0 and c_idx is not None:  # start the new branch at its bifurcation point
            at = [j for j, (kind, i) in enumerate(zip(kinds, c_idx, strict=True))
                  if kind == "bifurcation" and i == sel[0]]
            if at:
                x, y = np.r_[c_w[at[0]], x], np.r_[c_lam[at[0]], y]
        ax.plot(x, y, "-o", ms=3.5, lw=1.5, color=f"C{int(b)}", label=names.get(int(b), f"branch {int(b)}"))
    for kind, cl, cw in zip(kinds, c_lam, c_w, strict=True):
        marker, colour = ("*", "C3") if kind == "bifurcation" else ("D", "C1")
        ax.plot([cw], [cl], marker, ms=13 if marker == "*" else 8, color=colour, mec="k", mew=0.6, zorder=5,
                label=f"{kind}, λ = {cl:.5g}")
    ax.set_xlabel(_axis_label(ds["monitor"], "displacement"))
    ax.set_ylabel("load factor λ")
    ax.set_title(title if title is not None else "load–displacement")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize="small", loc="best")
    if "comment" in ds["load_factor"].attrs:
        ax.annotate(str(ds["load_factor"].attrs["comment"]), (0.01, 0.01), xycoords="figure fraction",
                    fontsize="x-small", color="0.35")
    if path is not None:
        fig.savefig(pathlib.Path(path), dpi=120)
    return fig


def plot_continuation(
    ds: xr.Dataset, path: str | os.PathLike | None = None, snapshots: int = 6, title: str | None = None
) -> Figure:
    """Quick-look figure of a continuation result: the load–displacement chart
    (:func:`plot_load_displacement`) beside ``snapshots`` shapes along the path coloured by λ
    (when the result holds ``position``; the initial configuration dashed).

    Parameters
    ----------
    ds : xarray.Dataset
        A continuation result.
    path : path-like, optional
        Where to save the figure.
    snapshots : int
        Number of shapes drawn, evenly spaced along the path (the last point included).
    title : str, optional
        Figure title (default: the Dataset's ``title`` attribute).

    Returns
    -------
    matplotlib.figure.Figure
    """
    from matplotlib.figure import Figure

    shapes = "position" in ds and ds["position"].ndim == 3 and ds["position"].shape[-1] in (2, 3)
    ncols = 2 if shapes else 1
    fig = Figure(figsize=(6.0 * ncols, 4.8), layout="constrained")
    plot_load_displacement(ds, ax=fig.add_subplot(1, ncols, 1))
    if shapes:
        pos = np.asarray(ds["position"].values, dtype=float)
        grid = tuple(int(k) for k in np.atleast_1d(ds.attrs.get("grid_shape", [pos.shape[1]])))
        if len(grid) > 1 and int(np.prod(grid)) == pos.shape[1]:  # a surface or a block: its node lines
            pos = pos.reshape(pos.shape[0], *grid, pos.shape[-1])
        idx = _snapshot_indices(pos.shape[0], snapshots)
        lam = np.asarray(ds["load_factor"].values, dtype=float)
        ref = np.asarray(ds["initial_position"].values, dtype=float) if "initial_position" in ds else None
        if ref is not None and ref.ndim == 2 and pos.ndim == 4:
            ref = ref.reshape(pos.shape[1:])
        _draw_shapes(fig, (1, ncols, 2), [pos[i] for i in idx], lam[idx], "load factor λ", ref,
                     title="shapes along the path", ds=ds)
    fig.suptitle(title if title is not None else str(ds.attrs.get("title", "")))
    if path is not None:
        fig.savefig(pathlib.Path(path), dpi=120)
    return fig


def plot_static(ds: xr.Dataset, path: str | os.PathLike | None = None, title: str | None = None,
                field: str | None = None, slice: str | None = None) -> Figure:
    """Quick-look figure of a static equilibrium (:func:`cartan.statics.solve_static`).

    Panels: the equilibrium shape (the initial configuration dashed, when the result holds
    ``initial_position``); for d = 1 the displacement components against the material
    coordinate ``u``; and the Newton residual norm at every iteration.

    Parameters
    ----------
    ds : xarray.Dataset
        A static result (one frame along ``time``, ``newton_residual`` along ``iteration``).
    path : path-like, optional
        Where to save the figure.
    title : str, optional
        Figure title (default: the Dataset's ``title`` attribute).
    field : str, optional
        For a surface or a solid, the node variable the equilibrium is coloured by, or one
        component ``"NAME[a,b]"`` of a variable with dimensions beyond the nodes (see
        :func:`plot_run`).
    slice : str, optional
        For a solid, the material slice ``"u"``, ``"v"``, ``"w"`` or ``"AXIS=INDEX"`` also
        drawn (see :func:`plot_run`).

    Returns
    -------
    matplotlib.figure.Figure
    """
    from matplotlib.figure import Figure

    pts = _points(ds)
    ref = np.asarray(ds["initial_position"].values, dtype=float) if "initial_position" in ds else None
    cut = _parse_slice(slice, ds, pts) if slice is not None else None
    curve = pts is not None and pts.ndim == 3
    panels = (pts is not None) + (curve and ref is not None) + (cut is not None) + 1
    fig = Figure(figsize=(5.2 * panels, 4.6), layout="constrained")
    slot = 1
    if _is_solid(pts):
        both = pts if ref is None or ref.shape != pts.shape[1:] else np.stack([ref, pts[-1]])
        _draw_solid_panels(fig, [(1, panels, 1), (1, panels, 2)], ds, both, field, "equilibrium", cut)
        slot += 1 + (cut is not None)
    elif _is_surface(pts):
        both = pts if ref is None or ref.shape != pts.shape[1:] else np.stack([ref, pts[-1]])
        _draw_surface_panel(fig, (1, panels, slot), ds, both, field, "equilibrium")
        slot += 1
    elif pts is not None:
        _draw_shapes(fig, (1, panels, slot), [pts[-1]], None, "", ref, title="equilibrium", ds=ds)
        slot += 1
    if curve and ref is not None:
        ax = fig.add_subplot(1, panels, slot)
        u = np.asarray(ds["u"].values, dtype=float) if "u" in ds.coords else np.arange(pts.shape[1], dtype=float)
        disp = pts[-1] - ref
        k = disp.shape[-1]
        for a, name in enumerate(["x", "y", "z"][:k] if k <= 3 else [f"x{i}" for i in range(k)]):
            ax.plot(u, disp[:, a], label=f"{name}")
        ax.set_xlabel("material coordinate u")
        ax.set_ylabel("displacement")
        ax.set_title("displacement from the initial configuration")
        if "measure" in ds.attrs:
            ax.annotate(f"{ds.attrs['measure']} = {float(ds.attrs['measured_displacement']):.6g}", (0.02, 0.02),
                        xycoords="axes fraction", fontsize="small")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize="small")
        slot += 1
    ax = fig.add_subplot(1, panels, slot)
    hist = np.asarray(ds["newton_residual"].values, dtype=float)
    ax.semilogy(np.arange(hist.size), np.maximum(hist, 1e-300), "-o", ms=4)
    ax.set_xlabel("Newton iteration")
    ax.set_ylabel("residual ‖w·W‖₂")
    ax.set_title(f"Newton: {int(ds.attrs.get('newton_iterations', hist.size - 1))} iterations")
    ax.grid(True, which="both", alpha=0.3)
    fig.suptitle(title if title is not None else str(ds.attrs.get("title", "")))
    if path is not None:
        fig.savefig(pathlib.Path(path), dpi=120)
    return fig
