"""Reading by model within a budget per candidate pass, ranked by the coarse match."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from ottag_db.decode import Detector, DetectorParams
from ottag_db.decode.candidates import find_quads
from ottag_db.decode.model_budget import rank_for_model, ranking_score, ranking_scores
from ottag_db.printing import scenes as sc

_READ_BY_MODEL = "by model: ρ"  # what a refused reading by model adds to its rejection's detail
_PASSED_OVER = "not read by model"


@given(st.lists(st.floats(-1, 1), max_size=30), st.integers(0, 8))
def test_the_budget_goes_to_the_best_scores_in_the_detectors_order(scores: list[float], budget: int) -> None:
    read, left = rank_for_model(scores, budget)
    assert sorted(read + left) == list(range(len(scores)))
    assert read == sorted(read) and len(read) == min(budget, len(scores))
    if read and left:
        assert min(scores[i] for i in read) >= max(scores[i] for i in left)


def _blobs(rng: np.random.Generator) -> list[tuple[np.ndarray, np.ndarray]]:
    """Dark foreshortened quads with a bright disc inside, around the frame's centre: each is a
    candidate no reading decodes, and matches printed tags about as well as a tag's own rough
    outline nearly edge-on."""
    patch = np.full((32, 32), 40, np.uint8)
    cv2.circle(patch, (16, 16), 7, 220, -1)
    out = []
    for i in range(30):
        x, y = 40 + (i % 6) * 95, 40 + (i // 6) * 100
        if 200 < x < 440 and 140 < y < 340:
            continue  # the tag's place
        w = rng.uniform(40, 70)
        out.append((patch, np.array([[w, rng.uniform(-10, 10), x], [0, 0.6 * w, y], [0, 0, 1.0]])))
    return out


@pytest.mark.parametrize("seed", [1, 2])
def test_a_tag_nearly_edge_on_among_clutter_is_read_within_the_budget(printed, seed) -> None:
    """Among 20 candidates for reading by model, the frame spends at most the budget per pass,
    and the tag seen at 84–85° is still read by model: a later pass outlines it anew, where it
    competes with few others. Without the budget every candidate is read."""
    lookup, tags = printed
    rng = np.random.default_rng(seed)
    tag = tags[seed % len(tags)]
    spec = sc.posed_spec(tag, rng, 98.0, 84.0 + seed % 2, "normal" if seed % 2 else "inverted")
    image = sc.render_scene((480, 640), [spec], rng, extra=_blobs(rng), blur=0.5, noise=2.0, jpeg=90).image
    budget = 2
    dets, rejected = Detector(lookup, DetectorParams(model_max_reads=budget)).detect_with_rejections(image)
    assert [(d.lambda_text, d.model_correlation is not None) for d in dets] == [(tag.lambda_text, True)]
    refused_by_model = sum(_READ_BY_MODEL in r.detail for r in rejected)
    assert refused_by_model + 1 <= 2 * budget  # the tag's pass and the one before it
    assert sum(_PASSED_OVER in r.detail for r in rejected) >= 15
    unbounded = Detector(lookup, DetectorParams(model_max_reads=1000)).detect_with_rejections(image)
    assert sum(_READ_BY_MODEL in r.detail for r in unbounded[1]) >= 15
    assert not any(_PASSED_OVER in r.detail for r in unbounded[1])


def test_no_budget_means_no_reading_by_model(printed) -> None:
    """``model_max_reads=0`` reads nothing by model, and says so in the rejections."""
    lookup, tags = printed
    rng = np.random.default_rng(0)
    spec = sc.posed_spec(tags[0], rng, 98.0, 84.0, "inverted")
    image = sc.render_scene((480, 640), [spec], rng, blur=0.5, noise=2.0, jpeg=90).image
    assert [d.model_correlation is not None for d in Detector(lookup).detect(image)] == [True]
    dets, rejected = Detector(lookup, DetectorParams(model_max_reads=0)).detect_with_rejections(image)
    assert all(d.model_correlation is None for d in dets)
    assert any(_PASSED_OVER in r.detail for r in rejected)


def test_candidates_ranked_together_score_as_one_by_one(printed) -> None:
    """The queue of a pass is ranked by one product over all its candidates' views
    (:func:`ranking_scores`): each candidate scores as :func:`ranking_score` scores it alone."""
    lookup, tags = printed
    rng = np.random.default_rng(3)
    spec = sc.posed_spec(tags[3], rng, 98.0, 82.0, "normal")
    image = sc.render_scene((480, 640), [spec], rng, extra=_blobs(rng), blur=0.5, noise=2.0, jpeg=90).image
    det = Detector(lookup)
    bank = det._bank  # the detector's templates (read only)
    assert bank is not None
    quads = find_quads(image, "adaptive", det.params) + find_quads(image, "otsu", det.params)
    assert len(quads) >= 15
    alone = [ranking_score(image, q, bank, det.params) for q in quads]
    # float32 products: BLAS sums a product of another shape in another order, which moves a
    # correlation by a few units of float32's last place (1.3e-6 with NumPy 2.4's OpenBLAS 0.3.31)
    np.testing.assert_allclose(ranking_scores(image, quads, bank, det.params), alone, atol=1e-5)
    assert ranking_scores(image, [], bank, det.params) == []
