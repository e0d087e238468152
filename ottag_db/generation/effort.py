"""How hard the realization searches per set (see :mod:`ottag_db.generation.realize`)."""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ottag_db.generation.batch_ascent import AscentSchedule

__all__ = ["RealizeEffort", "default_effort", "rescue_efforts"]


@dataclass(frozen=True)
class RealizeEffort:
    """How hard to search for one set.

    - ``starts``: continuous optimizations from the seed and random projective images;
    - ``hops``: further optimizations from random perturbations of the best so far
      (standard deviations cycling through ``hop_sigmas``, grid units);
    - ``roundings``: rounding variants (sub-pixel shifts and slight shrinks) tried per set;
    - ``searched_roundings``: best rounding variants refined by the integer local search;
    - ``maxiter``: SLSQP iteration limit; ``search_iters``: integer-search iteration limit;
    - ``hard_below``: sets whose best continuous MP (grid units) is below this count as
      *hard* and get ``hard_starts`` further SLSQP runs from uniformly random points (which
      land in other basins than the projective images of one realization) and
      ``exact_variants`` sub-pixel shifts / slight shrinks of the optimum, each rounded in
      all ``4^k`` ways (floor or ceiling per coordinate), of which the ``exact_keep`` best
      go to the search;
    - ``tilt_tol``: of the searched integer sets, those with MP ≥ (1 − ``tilt_tol``) · best
      (never crossing an MP step, see :mod:`ottag_db.generation.rounding`) compete on
      :func:`~ottag_db.generation.rounding.tilt_failures`;
    - ``ascent``: when set, the continuous stage of a whole work unit is
      :func:`~ottag_db.generation.batch_ascent.soft_min_ascent` (compiled, all sets at once)
      from ``starts`` starts per set (the input, then random projective images) instead of
      SLSQP; sets whose MP stays below ``polish_below`` (grid units) then get one SLSQP run
      (``maxiter``) from their ascent result (``hops`` and ``hard_starts`` are not used);
    - ``chunk``: sets per work unit of :func:`~ottag_db.generation.realize.realize_all`
      (0: :func:`~ottag_db.generation.realize.chunk_size`); the batched ascent gains from
      larger units.
    """

    starts: int = 3
    hops: int = 1
    hop_sigmas: tuple[float, ...] = (15.0, 5.0, 30.0, 60.0)
    roundings: int = 24
    searched_roundings: int = 3
    maxiter: int = 200
    search_iters: int = 200
    hard_below: float = 0.0
    hard_starts: int = 0
    exact_variants: int = 0
    exact_keep: int = 2
    tilt_tol: float = 0.03
    ascent: AscentSchedule | None = None
    polish_below: float = 0.0
    chunk: int = 0


def default_effort(k: int) -> RealizeEffort:
    """Search effort used for sets of ``k`` points.

    Few sets exist for ``k ≤ 7``, so they get many starts; for ``k = 8`` (3315 sets) the
    budget is a few SLSQP runs each (multi-starts rarely change the optimum there). From
    ``k = 9`` (158,817 sets) the continuous stage is the compiled soft-min ascent alone: 4,000
    steps from a step size of 3 grid units reach within 0.3 % of the mean MP of 300 steps plus
    an SLSQP polish (192 nine-point sets from projective images of their realizations: 3.149
    / 3.156 / 3.158 for 3,000 / 6,000 steps / with SLSQP) at a fifth of the time, since
    nine-point MPs on the grid are small and SLSQP polished nearly every set.

    Parameters
    ----------
    k : int
        Number of points.

    Returns
    -------
    RealizeEffort
        The effort the bundled data were generated with (k ≤ 8; these must not change, or
        ``generate`` no longer reproduces ``data/``).
    """
    if k <= 7:
        return RealizeEffort(starts=8, hops=16, roundings=64, searched_roundings=6, hard_below=np.inf, exact_variants=4)
    if k == 8:
        return RealizeEffort(starts=3, hops=0, hard_below=2.3, exact_variants=4)
    return RealizeEffort(
        starts=1,
        hops=0,
        maxiter=100,
        searched_roundings=2,
        search_iters=100,
        ascent=AscentSchedule(iters=4000, lr_start=3.0),
        polish_below=0.0,
        chunk=64,
    )


def rescue_efforts(k: int) -> tuple[RealizeEffort, ...]:
    """Per-set efforts, cheapest first, for a set the batched path could not round.

    First SLSQP from three starts, 24 roundings and the integer search (about 0.4 s for a
    nine-point set); if that fails too, the same with exact roundings (every floor/ceiling
    combination of a sub-pixel shift of the optimum, as for the hard eight-point sets; about
    9 s for nine points).

    Parameters
    ----------
    k : int
        Number of points.

    Returns
    -------
    tuple of RealizeEffort
        Efforts without ``ascent`` (the per-set path), to try in order.
    """
    first = RealizeEffort(starts=3, hops=0, search_iters=100 if k >= 9 else 200)
    return first, replace(first, hard_below=np.inf, exact_variants=1)
