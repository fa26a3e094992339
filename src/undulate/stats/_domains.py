"""The physical domain of each reported quantity, by its summary key's name, and the walk that checks them."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from ._estimate import Estimate, _g


DOMAINS: tuple[tuple[str, float, float, str], ...] = (
    (r"(^|_)r2($|_)", -math.inf, 1.0, "an R^2"),
    (r"spearman|kendall|pearson|correlation", -1.0, 1.0, "a correlation"),
    (r"(^|_)(rms|std)($|_)", 0.0, math.inf, "a root mean square or a spread"),
    (r"rho_tilde|density", 0.0, math.inf, "a density"),
    (r"width", 0.0, math.inf, "a width"),
    (r"fraction", 0.0, 1.0, "a fraction"),
    (r"^n_|(^|_)count($|_)|^runs_needed$", 0.0, math.inf, "a count"),
)
"""The physical domain of a summary's quantity by its key's name: ``(pattern, low, high, what)``, the
first whose regular expression is found in the key wins (``"spearman_k_vs_d"`` is a correlation,
``"threshold_rho_tilde"`` a density, ``"rms_interval_width"`` a root mean square).  A key no pattern
names has no domain; the items of a list, and of a dict keyed by numbers (``{"3": ..., "5": ...}``),
take their key's."""


def domain_of(key: str) -> tuple[float, float, str] | None:
    """``(low, high, what)``: the physical domain of the quantity a summary key names (:data:`DOMAINS`),
    None where no pattern names it."""
    import re

    for pattern, lo, hi, what in DOMAINS:
        if re.search(pattern, str(key)):
            return lo, hi, what
    return None


def _is_label(key: Any) -> bool:
    """A dict key that labels an item (a number: an N, a phi_max) rather than naming a quantity."""
    try:
        float(key)
    except (TypeError, ValueError):
        return False
    return True


def _finite_number(v: Any) -> bool:
    return (isinstance(v, int | float | np.integer | np.floating) and not isinstance(v, bool | np.bool_)
            and math.isfinite(float(v)))


def domain_violations(obj: Any, key: str = "", _domain: tuple[float, float, str] | None = None,
                      _path: str = "") -> list[str]:
    """Every number in ``obj`` (a study's summary, a claim's value: nested dicts, lists, arrays and
    :meth:`Estimate.to_dict` dicts) that lies outside the physical domain its key names
    (:func:`domain_of`), one line each naming where it is, the number or interval, and the domain.  An
    estimate's value and both ends of its interval are checked; NaN and missing ends (None) are not
    numbers to check.  ``key``: the name of ``obj`` itself (its domain, where it is a number or an
    estimate).  Empty when every number is inside its domain."""
    dom = domain_of(key) if key and not _is_label(key) else None
    dom = dom or _domain
    path = _path or str(key)
    if isinstance(obj, Estimate):
        obj = obj.to_dict()
    if isinstance(obj, np.ndarray):
        obj = obj.tolist()
    out: list[str] = []
    if isinstance(obj, dict) and "value" in obj and "ci95" in obj:  # an Estimate.to_dict
        if dom is None:
            return out
        lo, hi, what = dom
        ci = [v for v in (obj.get("ci95") or []) if _finite_number(v)]
        nums = [obj["value"]] if _finite_number(obj.get("value")) else []
        bad = [float(v) for v in nums + ci if not lo <= float(v) <= hi]
        if bad:
            out.append(f"{path}: {what} {_g(obj['value']) if nums else 'n/a'} "
                       f"[{', '.join('n/a' if v is None else _g(v) for v in (obj.get('ci95') or [None, None]))}]"
                       f" outside its domain [{_g(lo)}, {_g(hi)}]")
        return out
    if isinstance(obj, dict):
        for k, v in obj.items():
            inherit = dom if _is_label(k) else None
            out += domain_violations(v, str(k), inherit, f"{path}.{k}" if path else str(k))
        return out
    if isinstance(obj, list | tuple):
        for i, v in enumerate(obj):
            out += domain_violations(v, "", dom, f"{path}[{i}]")
        return out
    if dom is not None and _finite_number(obj) and not dom[0] <= float(obj) <= dom[1]:
        out.append(f"{path}: {dom[2]} {_g(float(obj))} outside its domain [{_g(dom[0])}, {_g(dom[1])}]")
    return out


def check_domains(obj: Any, where: str) -> None:
    """Raise :class:`~undulate.errors.UndulateError` naming ``where`` and every number of ``obj``
    outside its physical domain (:func:`domain_violations`); a reported interval outside its
    quantity's domain comes from a method that does not fit the quantity, and is refused, never
    clipped."""
    bad = domain_violations(obj)
    if bad:
        from ..errors import UndulateError

        raise UndulateError(f"{where}: {len(bad)} number(s) outside their physical domain: " + "; ".join(bad[:10])
                            + (f"; and {len(bad) - 10} more" if len(bad) > 10 else ""))


def estimates(values: Sequence[Estimate]) -> list[dict[str, Any]]:
    """``[e.to_dict() for e in values]``."""
    return [e.to_dict() for e in values]
