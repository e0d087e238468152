"""Normal tags of the tilt sweep nearly edge-on (84–86°, benchmarks/decode_sweeps.py): data areas a
few pixels thin that the detector's candidate passes and its reading by model must still read."""

from __future__ import annotations

import numpy as np
import pytest

from ottag_db.decode import Detector
from ottag_db.printing import scenes as sc


def _normal_tag_readings(bundled, prefix, hom, blur, noise, gradient):
    """A normal tag (its ID starting with ``prefix``) rendered at ``hom`` with seeds 0 and 1
    (JPEG 85): its ID and the IDs read on each render."""
    lookup, records = bundled
    tag = next(t for t in records if t.lambda_text.startswith(prefix))
    det = Detector(lookup)
    readings = []
    for seed in range(2):
        spec = sc.TagSpec(tag.points, tag.triangles, np.array(hom), "normal", placement=tag.placement)
        image = sc.render_scene(
            (480, 640), [spec], np.random.default_rng(seed), blur=blur, noise=noise, gradient=gradient, jpeg=85
        ).image
        readings.append([d.lambda_text for d in det.detect(image)])
    return tag.lambda_text, readings


@pytest.mark.parametrize(
    ("prefix", "hom", "blur", "noise"),
    [
        (
            "8:06543210006254311003654224304323310206",
            [[60.419384, -33.663727, 317.052953], [78.800176, -63.758253, 282.174458], [0.137874, 0.067553, 1]],
            0.28,
            1.16,
        ),
        (
            "8:06543210002654311405432220104653312205",
            [[-55.759111, 61.020085, 278.820695], [-26.043354, -63.776306, 280.305849], [-0.127693, -0.020423, 1]],
            0.66,
            2.91,
        ),
    ],
)
def test_a_normal_tag_nearly_edge_on_is_read(bundled, prefix, hom, blur, noise):
    """Normal 8-point tags of the tilt sweep at 84° and 86° (benchmarks/decode_sweeps.py, 21 cm
    at 1.5 m): the data area found is 4–6 px thin, and without its 2 px border band nothing of it
    was left to threshold (``low_contrast`` without grey levels) on 4 of 4 renders each, while
    the same poses inverted read. A 1 px band keeps the inside, and the tag reads (by model)."""
    lam, readings = _normal_tag_readings(bundled, prefix, hom, blur, noise, 0.1)
    assert readings == [[lam], [lam]]


@pytest.mark.parametrize(
    ("prefix", "hom", "blur", "noise", "gradient"),
    [
        (
            "8:06543210002654311405432220106453312005",
            [[61.485258, 31.982781, 284.990413], [93.624229, 31.538945, 229.710875], [0.017413, 0.149871, 1]],
            0.77,
            0.65,
            0.22,
        ),
        (
            "8:06543210001652431505413220106354312004",
            [[-82.456588, -60.087907, 382.456866], [16.562191, -38.81507, 265.255321], [0.025413, -0.129516, 1]],
            0.76,
            1.5,
            0.23,
        ),
    ],
)
def test_a_normal_tag_nearly_edge_on_in_a_blurred_frame_is_read(bundled, prefix, hom, blur, noise, gradient):
    """Normal 8-point tags of the tilt sweep at 84° (benchmarks/decode_sweeps.py, 21 cm at
    1.5 m) in frames blurred by σ 0.76–0.77 px: read by model, the tag seen aligned with ρ
    0.93–0.94 and a lead of 0.4, but judged with one fixed camera blur (σ 0.45 px) its sliver
    edges misfit by 0.29–0.31, over the limit, on both renders (the inverted tags of the same
    poses read). Judged with the blur that fits the tag's outline, the tag reads."""
    lam, readings = _normal_tag_readings(bundled, prefix, hom, blur, noise, gradient)
    assert readings == [[lam], [lam]]


@pytest.mark.parametrize(
    ("prefix", "hom", "blur", "noise", "gradient"),
    [
        (
            "8:0654321000165432150543212010365431230543423010655341200664523100",
            [[50.208591, -95.590088, 367.213488], [48.667811, -35.407594, 223.186839], [0.15004, 0.009577, 1]],
            0.68,
            1.0,
            0.01,
        ),
        (
            "8:0654321000165432150543212010635431200465423320435341020664521300",
            [[-19.4148, -42.910572, 314.381645], [68.82158, -65.158294, 216.362619], [-0.053206, -0.116228, 1]],
            0.64,
            2.02,
            0.28,
        ),
    ],
)
def test_a_thin_tag_outlined_better_by_the_global_threshold_is_read(bundled, prefix, hom, blur, noise, gradient):
    """Normal 8-point tags of the tilt sweep at 84° and 86° (benchmarks/decode_sweeps.py, 21 cm
    at 1.5 m), 10–12 px thin. The local threshold's outline misses the data area by 5–9 px at a
    corner and no reading decodes it; the global threshold outlines it within 2–3 px, but was
    dropped as the same candidate. Read again from that outline, the tag reads (by model); it
    read on none of 6 renders each before."""
    lam, readings = _normal_tag_readings(bundled, prefix, hom, blur, noise, gradient)
    assert readings == [[lam], [lam]]


@pytest.mark.parametrize(
    ("prefix", "hom", "blur", "noise", "gradient"),
    [
        (
            "8:06543210006354211003654223304333310206",
            [[-95.871203, -25.604264, 346.291447], [5.966462, -41.992526, 260.572075], [-0.023344, -0.126657, 1]],
            0.59,
            2.7,
            0.08,
        ),
        (
            "8:06543210001645321505432120103654322304",
            [[54.570271, -102.38266, 343.301434], [42.77418, 13.438711, 242.327915], [0.150519, 0.008177, 1]],
            0.58,
            0.59,
            0.04,
        ),
    ],
)
def test_a_thin_normal_tag_found_as_a_hole_of_its_quiet_zone_is_read(bundled, prefix, hom, blur, noise, gradient):
    """Normal 8-point tags of the tilt sweep at 84° and 86° (21 cm at 1.5 m) that the dark
    passes never outlined well enough to read: the pass over the bright quiet zone's holes
    (``find_quads(..., "bright_holes")``) outlines the data area as an inverted tag's is
    outlined, and the tag reads; it read on neither render before."""
    lam, readings = _normal_tag_readings(bundled, prefix, hom, blur, noise, gradient)
    assert readings == [[lam], [lam]]
