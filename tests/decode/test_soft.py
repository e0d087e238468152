"""Soft decoding: candidate enumeration by flipping ambiguous triples, and the acceptance rule."""

from __future__ import annotations

import math

import numpy as np

from ottag_db.core.canonical import canonical_batch, canonical_form
from ottag_db.core.flips import flip_neighbours
from ottag_db.core.single_set import orientation_table
from ottag_db.decode.soft import (
    Scored,
    SoftChoice,
    ambiguous_triples,
    choose,
    confirms,
    flip_readings,
    layout_matches,
    observed_triangles,
)

#: Five points in general position; point 4 is then put near the line through points 0 and 1.
BASE = np.array([[0, 0], [100, 0], [50, 80], [20, 40], [60, 30.0]])


def _near_line(offset: float) -> np.ndarray:
    """BASE with point 4 at signed distance ``offset`` from the line 0 → 1 (y = offset)."""
    pts = BASE.copy()
    pts[4] = [60, offset]
    return pts


def test_ambiguous_triples_are_the_near_collinear_ones() -> None:
    table = orientation_table(_near_line(0.4))
    assert ambiguous_triples(table, 1.0) == [(0, 1, 4)]
    assert ambiguous_triples(table, 0.1) == []
    # a point near the crossing of two lines makes two triples ambiguous, nearest first
    pts = BASE.copy()
    pts[3] = [50.3, 0.2]  # near line 0-1 (0.2) and near line 2-4 (x from 50 to 60)
    pts[4] = [50.0, -30.0]
    tri = ambiguous_triples(orientation_table(pts), 1.0)
    assert tri[0] == (0, 1, 3) and set(tri) == {(0, 1, 3), (2, 3, 4)}


def test_one_flip_is_the_point_across_the_line() -> None:
    measured = _near_line(0.4)
    table = orientation_table(measured)
    readings = flip_readings(table, ambiguous_triples(table, 1.0), 1)
    assert [r.flips for r in readings] == [(), ((0, 1, 4),)]
    assert readings[0].lambda_text == canonical_form(measured).text
    across = _near_line(-0.4)
    truth = canonical_form(across)
    assert readings[1].lambda_text == truth.text
    assert readings[0].lambda_text != readings[1].lambda_text
    # the flipped chirotope, relabeled, is the one of the set with the point across the line
    lab = readings[1].minimal[0]
    assert confirms(measured, readings[1].flips, lab, across[list(truth.labeling)])
    assert not confirms(measured, (), lab, across[list(truth.labeling)])
    assert not confirms(measured, readings[1].flips, lab, measured[list(truth.labeling)])


def test_two_flips_and_no_flips() -> None:
    pts = BASE.copy()
    pts[3] = [50.3, 0.2]
    pts[4] = [50.0, -30.0]
    table = orientation_table(pts)
    triples = ambiguous_triples(table, 1.0)
    assert [r.flips for r in flip_readings(table, triples, 0)] == [()]
    readings = flip_readings(table, triples, 2)
    # point 3 moved across both lines at once is the reading with both triples flipped
    both = pts.copy()
    both[3] = [49.7, -0.2]
    texts = {r.flips: r.lambda_text for r in readings}
    assert texts[tuple(triples)] == canonical_form(both).text
    assert all(len(r.flips) <= 2 for r in readings) and len(readings) <= 4


def test_acceptance_rule() -> None:
    bound, gap = 1.5, 0.2  # the lead must be 0.3 px
    assert choose([Scored(True, 0.3), Scored(False, 1.9)], bound, gap).index == 0
    assert choose([Scored(False, 2.0), Scored(True, 0.4), Scored(False, math.inf)], bound, gap).index == 1
    # a lone candidate must pass with the lead to spare below the bound
    assert choose([Scored(True, 1.1)], bound, gap).index == 0
    assert choose([Scored(True, 1.3)], bound, gap).index is None
    # two that verify: refused, whatever their fits
    assert choose([Scored(True, 0.2), Scored(True, 1.4)], bound, gap) == SoftChoice(None, "2 of 2 candidates verify")
    # one verifies, the next fails just outside the bound: too close to call
    assert choose([Scored(True, 1.3), Scored(False, 1.55)], bound, gap).index is None
    assert choose([Scored(False, 2.0)], bound, gap).index is None
    assert choose([], bound, gap).index is None


def _line(a: np.ndarray, b: np.ndarray) -> tuple[float, float, float]:
    d = b - a
    n = np.array([-d[1], d[0]]) / np.hypot(d[0], d[1])
    return float(n[0]), float(n[1]), float(n @ a)


def test_observed_triangles_and_layouts() -> None:
    # two triangles sharing point 2: (0, 1, 2) and (2, 3, 4)
    pts = np.array([[0, 0], [10, 0], [5, 8], [12, 14], [2, 16.0]])
    tris = [(0, 1, 2), (2, 3, 4)]
    per_point: list[list[tuple[float, float, float]]] = [[] for _ in pts]
    for t in tris:
        for i in range(3):
            a, b = t[i], t[(i + 1) % 3]
            line = _line(pts[a], pts[b])
            per_point[a].append(line)
            per_point[b].append(line)
    lines = [(np.array([ln[:2] for ln in ls]), np.array([ln[2] for ln in ls])) for ls in per_point]
    observed = observed_triangles(lines)
    assert observed == {frozenset(t) for t in tris}
    # canonical labels → points: label l is point labeling[l]
    labeling = (4, 3, 2, 1, 0)
    assert layout_matches(observed, [(0, 1, 2), (2, 3, 4)], labeling)
    assert not layout_matches(observed, [(0, 1, 3), (2, 3, 4)], labeling)
    # a line of one point only: structure unknown
    broken = list(lines)
    broken[0] = (lines[0][0][:1], lines[0][1][:1])
    assert observed_triangles(broken) is None


def test_single_flips_are_the_flip_graph_neighbours(bundled_sets: dict[int, np.ndarray]) -> None:
    """With every triple treated as ambiguous, the confirmed one-flip readings of a set that the
    complete list holds are exactly its flip-graph neighbours (:func:`flip_neighbours`)."""
    sets = bundled_sets[6].astype(np.float64)
    both = np.concatenate([sets, sets * np.array([-1.0, 1.0])])  # every order type: mirrors too
    batch = canonical_batch(both)
    texts = batch.texts()
    keep = sorted({t: i for i, t in enumerate(texts)}.values())
    canon = np.stack([both[i][batch.labelings[i]] for i in keep])
    names = [texts[i] for i in keep]
    index = {t: i for i, t in enumerate(names)}
    edges = flip_neighbours(canon, names)
    for src in range(0, len(names), 3):
        pts = canon[src]
        table = orientation_table(pts)
        everything = ambiguous_triples(table, math.inf)
        found = set()
        for r in flip_readings(table, everything, 1):
            j = index.get(r.lambda_text)
            if r.flips and j is not None and confirms(pts, r.flips, r.minimal[0], canon[j]):
                found.add(r.lambda_text)
        assert found == {names[e.target] for e in edges if e.source == src}
