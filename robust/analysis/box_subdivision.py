"""Branch and bound on a parameter box: certify a box by certifying sub-boxes.

:func:`subdivide` halves the sub-boxes whose certificate fails, along the coordinate that
:func:`split_coordinate` picks from a result's first-order sensitivities, until every
sub-box is certified, a centre violates, or the box budget or deadline runs out. It knows
nothing of what is certified (the eigenvalue enclosures, the margins' box certificates
pass their own ``certify``), so it stands apart from them.
"""

from __future__ import annotations

import collections
import math
import time
from collections.abc import Callable

import numpy as np

__all__ = ["split_coordinate", "subdivide"]


def split_coordinate(
    res: dict,
    decay_rate: float,
    open_: np.ndarray,
    margins: np.ndarray | None = None,
    remainder: np.ndarray | None = None,
) -> int:
    """The coordinate to halve when a box fails: the one that moves the eigenvalues most
    relative to their distance to the line ``Re s = -decay_rate``.

    A coordinate moves the eigenvalues through the first-order term (``sensitivity``) and
    through the spread of its derivative over the box (``remainder``): a parameter that
    enters at second order about the centre (a derivative zero there) has no first-order
    sensitivity but still widens every enclosure, and halving it shrinks that spread.

    Parameters
    ----------
    res : dict
        A result of :func:`enclose_eigenvalues` (its ``eigs`` and ``sensitivity``).
    decay_rate : float
        The required decay rate, >= 0.
    open_ : ndarray of bool, shape (d,)
        Coordinates with a nonzero width (only those can be halved).
    margins : ndarray, shape (n,), optional
        Each eigenvalue's distance to the edge of the region (default: to the line
        ``Re s = -decay_rate``).
    remainder : ndarray, shape (d,), optional
        Each coordinate's share of the remainder bound, ``h_p ||rad(dA/dt_p)||_2`` (added
        to every eigenvalue's sensitivity to it).
    """
    if margins is None:
        margins = -(res["eigs"].real + decay_rate)
    margins = np.maximum(np.asarray(margins, float), 1e-9)
    sens = res["sensitivity"]
    if remainder is not None:
        sens = sens + np.asarray(remainder, float)[None, :]
    score = (sens / margins[:, None]).sum(axis=0)
    score = np.where(open_, np.nan_to_num(score, nan=0.0, posinf=1e300), -1.0)
    return int(np.argmax(score))


def subdivide(
    certify: Callable[[np.ndarray, np.ndarray], dict],
    lo: np.ndarray,
    hi: np.ndarray,
    *,
    max_boxes: int,
    deadline: float = math.inf,
    wave: int = 1,
    certify_many: Callable[[list], list] | None = None,
) -> tuple[bool, dict]:
    """Branch and bound: certify a box by certifying sub-boxes, halving the ones that fail.

    The boxes wait in a queue (breadth first: the larger boxes, which fail more often, are
    tried before their descendants). Each step takes up to ``wave`` boxes from its front
    and certifies them together (``certify_many``, e.g. on several processes), then reads
    the answers in the order taken. Whether the box is certified does not depend on
    ``wave``: every sub-box's answer and split depend on that sub-box alone, so the tree
    of sub-boxes is the same, and the box is certified exactly when that tree holds at most
    ``max_boxes`` boxes and none whose centre violates; only the statistics of a failure
    (boxes tried, the reason met first) do. The search stops as soon as the boxes tried
    plus those waiting exceed ``max_boxes``: each waiting box is a box of the tree, so the
    tree cannot fit, and the boxes it would still try cannot change the verdict. Every
    failed box leaves one more waiting, so that stop comes after about ``max_boxes / 2``
    failures; breadth first, few certified boxes are tried before them (a scale of the
    robust margin searches that fails on its budget: about 207 boxes of 400 tried, against
    207-399 depth first, the same verdicts).

    Parameters
    ----------
    certify : callable
        ``certify(lo, hi)`` returns a dict with ``certified`` (bool), ``centre_violates``
        (bool: the box holds a point that fails, so no subdivision can succeed), ``check``
        (float, < 0 when certified) and ``split`` (the coordinate to halve on failure).
    lo, hi : ndarray, shape (d,)
        The box.
    max_boxes : int
        Boxes tried before giving up (sets the result on every machine).
    deadline : float
        ``time.perf_counter()`` value after which the search stops (a safety limit; the
        statistics say when it was hit).
    wave : int
        Boxes taken from the queue per step (1: one at a time).
    certify_many : callable, optional
        ``certify_many([(lo, hi), ...])`` returns the answers of ``certify`` for those boxes,
        in order (default: ``certify`` on each in turn).

    Returns
    -------
    certified : bool
    stats : dict
        ``boxes`` tried, ``certified_boxes``, ``worst_check`` over the certified boxes,
        ``reason``, ``routes`` (certified boxes per ``route`` named by ``certify``) and,
        when the budget is exceeded, ``pending`` (boxes left waiting).
    """
    many = certify_many or (lambda boxes: [certify(a, b) for a, b in boxes])
    queue = collections.deque([(np.asarray(lo, float), np.asarray(hi, float))])
    stats = {"boxes": 0, "certified_boxes": 0, "worst_check": -math.inf}
    while queue:
        # every box waiting in the queue is one more box of the tree: once the boxes tried
        # and those waiting exceed the budget, the tree cannot fit in it (the same verdict as
        # trying them, at about half the cost of a failure)
        if stats["boxes"] + len(queue) > max_boxes:
            return False, dict(stats, reason="box budget", pending=len(queue))
        if time.perf_counter() > deadline:
            return False, dict(stats, reason="time limit (result depends on the machine)")
        batch = [queue.popleft() for _ in range(min(wave, len(queue), max_boxes - stats["boxes"]))]
        stats["boxes"] += len(batch)
        for (a, b), res in zip(batch, many(batch)):
            if res["certified"]:
                stats["certified_boxes"] += 1
                if res.get("route"):
                    routes = stats.setdefault("routes", {})
                    routes[res["route"]] = routes.get(res["route"], 0) + 1
                stats["worst_check"] = max(stats["worst_check"], float(res["check"]))
                continue
            if res["centre_violates"]:
                return False, dict(stats, reason="a member violates the region")
            j = int(res["split"])
            mid = (a[j] + b[j]) / 2
            b1, a2 = b.copy(), a.copy()
            b1[j], a2[j] = mid, mid
            queue.extend([(a, b1), (a2, b)])
    return True, dict(stats, reason="certified")
