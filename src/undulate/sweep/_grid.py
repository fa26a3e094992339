"""The parameter grid of a sweep and its per-run seeds."""

from __future__ import annotations

import hashlib
import itertools
import json
import math
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import ParameterError

__all__ = ["Grid", "Run"]

#: Names the sweep itself puts on the merged Dataset; a grid axis may not use them.
RESERVED = frozenset({"replicate", "point", "seed", "run_failed"})

Scalar = bool | int | float | str


def _scalar(name: str, value: Any) -> Scalar:
    """A grid value as a plain Python scalar (numpy scalars unwrapped)."""
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, bool | int | str):
        return value
    if isinstance(value, float):
        if not math.isfinite(value):
            raise ParameterError(name, "finite numbers, strings or booleans", value)
        return value
    raise ParameterError(name, "scalars (a number, string or boolean)", value)


def _column(name: str, values: Sequence[Scalar]) -> tuple[Scalar, ...]:
    """One axis (or one key across explicit points), with a single type.

    Mixed ints and floats become floats; any other mix is an error, since the
    merged Dataset stores each axis as one typed array.
    """
    kinds = {type(v) for v in values}
    if kinds <= {int, float} and float in kinds:
        return tuple(float(v) for v in values)
    if len(kinds) > 1:
        raise ParameterError(name, "values of one type (all numbers, all strings or all booleans)", list(values))
    return tuple(values)


def _check_name(name: Any) -> str:
    if not isinstance(name, str) or not name.isidentifier():
        raise ParameterError("grid axis name", "a Python identifier", name)
    if name in RESERVED:
        raise ParameterError("grid axis name", f"not one of {sorted(RESERVED)} (the sweep uses those)", name)
    return name


def _canonical(value: Scalar) -> Scalar:
    """The form of a value that seeds hash: numbers as floats (1 == 1.0)."""
    if isinstance(value, bool | str):
        return value
    return float(value)


@dataclass(frozen=True)
class Run:
    """One run of a sweep: a grid point and one replicate of it."""

    index: int
    """Position of the point in :meth:`Grid.points` order."""
    replicate: int
    """Replicate number, 0 .. replicates-1."""
    point: dict[str, Scalar]
    """Parameter name -> value, as passed to the sweep function."""
    seed: int
    """Seed for this run, in [0, 2**63)."""

    @property
    def key(self) -> str:
        """File stem of the run in the store (``p3f9c0a1b2d4e5f60_r000``): 16 hex digits of its point's
        content hash, then the replicate.  By content, not position: a grid that grows by points (a
        later stage of a staged plan) finds every run it shares with the grid before it."""
        return f"p{_point_hex(self.point)}_r{self.replicate:03d}"


class Grid:
    """The parameter points of a sweep, each run ``replicates`` times.

    Either a cartesian product of ``axes`` (name -> values; the merged
    Dataset then has one dimension per axis, in the given order, then
    ``replicate``) or an explicit list of ``points`` (dicts with the same
    keys; the Dataset then has dimensions ``point`` and ``replicate``, and
    each key is a coordinate along ``point``).  Values are scalars: numbers
    (in the SI unit their name states), strings or booleans.

    Seeds: run ``(point, replicate)`` gets
    ``SeedSequence(seed, spawn_key=(*hash(point), replicate))``'s first
    63-bit word, where ``hash(point)`` is a SHA-256 of the point's
    names and values (numbers taken as floats).  A seed thus depends on what
    is run — never on the worker, the order, or the point's position in the
    grid — so refining a grid keeps every existing point's seed.

    >>> g = Grid(axes={"dphi_rad": [0.0, 1.0], "waves_per_body": [0.75, 1.0]}, replicates=2)
    >>> g.dims, g.shape, g.n_runs
    (('dphi_rad', 'waves_per_body'), (2, 2), 8)
    """

    __slots__ = ("_axes", "_points", "replicates", "seed")

    def __init__(
        self,
        axes: Mapping[str, Sequence[Any]] | None = None,
        *,
        points: Sequence[Mapping[str, Any]] | None = None,
        replicates: int = 1,
        seed: int = 0,
    ):
        if (axes is None) == (points is None):
            raise ParameterError("Grid", "given exactly one of axes= (a cartesian product) or points= (a list)", None)
        if isinstance(replicates, bool) or not isinstance(replicates, int | np.integer) or replicates < 1:
            raise ParameterError("replicates", "an integer >= 1", replicates)
        if isinstance(seed, bool) or not isinstance(seed, int | np.integer) or seed < 0:
            raise ParameterError("seed", "an integer >= 0", seed)
        self.replicates = int(replicates)
        self.seed = int(seed)
        self._axes: tuple[tuple[str, tuple[Scalar, ...]], ...] | None = None
        self._points: tuple[dict[str, Scalar], ...] | None = None
        if axes is not None:
            if not isinstance(axes, Mapping):
                raise ParameterError("axes", "a mapping of axis name -> sequence of values", axes)
            parsed = []
            for name, values in axes.items():
                _check_name(name)
                if isinstance(values, str | bytes) or not isinstance(values, Sequence | np.ndarray):
                    raise ParameterError(f"axes[{name!r}]", "a sequence of values", values)
                vals = _column(f"axes[{name!r}]", [_scalar(f"axes[{name!r}]", v) for v in np.asarray(values, dtype=object).ravel()])
                if not vals:
                    raise ParameterError(f"axes[{name!r}]", "at least one value", list(values))
                if len(set(vals)) != len(vals):
                    raise ParameterError(f"axes[{name!r}]", "distinct values (use replicates= for repeats)", list(vals))
                parsed.append((name, vals))
            self._axes = tuple(parsed)
        else:
            if isinstance(points, Mapping) or not isinstance(points, Sequence) or not points:
                raise ParameterError("points", "a non-empty list of dicts", points)
            keys = None
            for p in points:
                if not isinstance(p, Mapping):
                    raise ParameterError("points", "a list of dicts (parameter name -> value)", p)
                if keys is None:
                    keys = list(p)
                    for k in keys:
                        _check_name(k)
                elif set(p) != set(keys):
                    raise ParameterError("points", f"dicts that all have the keys {keys}", dict(p))
            assert keys is not None
            cols = {k: _column(f"points[*][{k!r}]", [_scalar(f"points[*][{k!r}]", p[k]) for p in points]) for k in keys}
            pts = tuple({k: cols[k][i] for k in keys} for i in range(len(points)))
            seen = set()
            for p in pts:
                t = tuple(p.values())
                if t in seen:
                    raise ParameterError("points", "distinct points (use replicates= for repeats)", p)
                seen.add(t)
            self._points = pts

    # ---- shape -----------------------------------------------------------
    @property
    def is_product(self) -> bool:
        """True for a cartesian product of axes, False for explicit points."""
        return self._axes is not None

    @property
    def names(self) -> tuple[str, ...]:
        """The parameter names of every point."""
        if self._axes is not None:
            return tuple(n for n, _ in self._axes)
        return tuple(self._points[0])  # type: ignore[index]

    @property
    def axes(self) -> dict[str, tuple[Scalar, ...]]:
        """Axis name -> values (product grids); parameter -> per-point values (explicit points)."""
        if self._axes is not None:
            return dict(self._axes)
        return {k: tuple(p[k] for p in self._points) for k in self.names}  # type: ignore[union-attr]

    @property
    def dims(self) -> tuple[str, ...]:
        """Dimensions of the grid in the merged Dataset (before ``replicate``)."""
        return self.names if self._axes is not None else ("point",)

    @property
    def shape(self) -> tuple[int, ...]:
        if self._axes is not None:
            return tuple(len(v) for _, v in self._axes)
        return (len(self._points),)  # type: ignore[arg-type]

    @property
    def n_points(self) -> int:
        return math.prod(self.shape)

    @property
    def n_runs(self) -> int:
        """Points times replicates."""
        return self.n_points * self.replicates

    def points(self) -> Iterator[dict[str, Scalar]]:
        """Every point, in row-major order of :attr:`dims`."""
        if self._axes is not None:
            names = self.names
            for combo in itertools.product(*(v for _, v in self._axes)):
                yield dict(zip(names, combo))
        else:
            for p in self._points:  # type: ignore[union-attr]
                yield dict(p)

    def runs(self) -> list[Run]:
        """Every run: each point, then each replicate, with its seed."""
        out = []
        for i, p in enumerate(self.points()):
            words = _point_hash(p)
            for r in range(self.replicates):
                out.append(Run(i, r, p, run_seed(self.seed, words, r)))
        return out

    # ---- identity --------------------------------------------------------
    def to_dict(self) -> dict[str, Any]:
        """A JSON-able description; equal dicts mean equal grids."""
        d: dict[str, Any] = {"replicates": self.replicates, "seed": self.seed}
        if self._axes is not None:
            d["axes"] = {n: list(v) for n, v in self._axes}
        else:
            d["points"] = [dict(p) for p in self._points]  # type: ignore[union-attr]
        return d

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> Grid:
        """Inverse of :meth:`to_dict`; unknown keys are rejected, not ignored."""
        unknown = sorted(set(d) - {"axes", "points", "replicates", "seed"})
        if unknown:
            raise ParameterError("grid", "a dict with keys among axes, points, replicates, seed", unknown)
        return cls(d.get("axes"), points=d.get("points"), replicates=d.get("replicates", 1), seed=d.get("seed", 0))

    def __eq__(self, other: object) -> bool:
        return isinstance(other, Grid) and self.to_dict() == other.to_dict()

    def __hash__(self) -> int:
        return hash(json.dumps(self.to_dict(), sort_keys=True))

    def __repr__(self) -> str:
        what = (
            "axes={" + ", ".join(f"{n!r}: <{len(v)} values>" for n, v in self._axes) + "}"
            if self._axes is not None
            else f"points=<{self.n_points} points>"
        )
        return f"Grid({what}, replicates={self.replicates}, seed={self.seed})"


def _point_digest(point: Mapping[str, Scalar]) -> bytes:
    text = json.dumps({k: _canonical(v) for k, v in point.items()}, sort_keys=True)
    return hashlib.sha256(text.encode()).digest()


def _point_hex(point: Mapping[str, Scalar]) -> str:
    """16 hex digits of the point's content hash (its runs' file stems in a store)."""
    return _point_digest(point)[:8].hex()


def _point_hash(point: Mapping[str, Scalar]) -> tuple[int, ...]:
    digest = _point_digest(point)
    return tuple(int.from_bytes(digest[i : i + 4], "little") for i in range(0, 32, 4))


def run_seed(base_seed: int, point_words: tuple[int, ...], replicate: int) -> int:
    """Seed of one run, in [0, 2**63): from the base seed, the point and the replicate."""
    ss = np.random.SeedSequence(base_seed, spawn_key=(*point_words, replicate))
    return int(ss.generate_state(1, np.uint64)[0] >> np.uint64(1))
