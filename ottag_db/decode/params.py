"""The decoder's settings: :class:`DetectorParams`, chosen once per
:class:`~ottag_db.decode.Detector` (its defaults are what the benchmarks measure)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from ottag_db.core.types import POLARITIES, Polarity
from ottag_db.errors import UsageError

__all__ = ["DetectorParams"]


@dataclass(frozen=True)
class DetectorParams:
    """Decoder settings (lengths in image pixels unless noted).

    Candidate search:

    - ``use_adaptive`` / ``use_otsu``: binarizations searched for data areas: local mean
      thresholding (window ``adaptive_block`` px, odd, 0 = automatic: about 1/16 of the shorter
      image side, at least 15; offset ``adaptive_c`` grey levels, less in a dim frame:
      :func:`~ottag_db.decode.image.threshold_offset`), then global Otsu for quads the first pass
      did not give, only when the adaptive pass decoded nothing, unless ``otsu_always``;
    - ``polarities``: which tag polarities to look for (a tuple; one name is accepted too);
    - ``min_quad_area_px``: smallest data-area area (px²; 256: a 21 cm tag at 8 m with f = 700
      px is 18 px wide, and such small data areas are read by model); ``min_quad_side_px``:
      shortest side;
    - ``max_candidates``: at most this many candidate quads (largest first) are read per frame;
    - ``last_resort_passes``: also run, on a frame the passes before read no tag in, the three
      candidate passes for what they miss: thin and small quads at full resolution (data areas
      seen nearly edge-on), the dark holes of the bright mask (a foreshortened normal data
      area as a hole of its quiet zone) and blurred tags outlined by the local range (see
      :mod:`~ottag_db.decode.candidates`). A frame whose tags read in the first passes never
      runs them, so False changes nothing there; on a frame without a tag they are two thirds
      of the time (the photographs of benchmarks/decode_photos.py). False gives up the tags
      only they read, measured in benchmarks/decode_sweeps.py ``--other`` and
      benchmarks/decode_degraded.py ``--params``: grazing views from about 82° on, and tags
      blurred by a long motion.

    Reading:

    - ``min_contrast``: grey levels between the dark and bright class inside the data area
      (and the least departure of a frame from its local mean, below which the global
      threshold's pass is not run: :func:`~ottag_db.decode.image.frame_has_contrast`);
    - ``min_triangle_area_px``: smaller components inside a data area are ignored as noise;
    - ``merge_radius_px`` / ``merge_radius_rel``: vertex estimates of different triangles are
      one (shared) point when the least-squares intersection of all their side lines lies
      within ``max(merge_radius_px, merge_radius_rel * sqrt(area))`` of each of these lines;
    - ``min_margin_px``: a reading whose smallest point-to-line distance is below this is
      rejected (default 1.0 px: the vertices are fitted to ~0.1–0.3 px, so an orientation
      cannot flip on a margin this large);
    - ``verify``: check the reading against the stored realizations (see
      :class:`~ottag_db.decode.Detector`);
    - ``max_reproj_px`` / ``max_reproj_rel``: reprojection bound
      ``max(max_reproj_px, max_reproj_rel * sqrt(data-area area))`` on the largest distance
      from a mapped realization point to a side line through its detected point (the
      homography is fitted to these point–line incidences, so a sharp tip, well measured
      across its sides but not along its axis, is judged across its sides);
    - ``check_quad`` / ``max_quad_error``: the data-area corners mapped back to the tag plane
      must form a parallelogram: ``|g0 − g1 + g2 − g3|`` at most ``max_quad_error`` times the
      mean side (the tag is placed by an affine map, so the square becomes a parallelogram);
    - ``allow_unknown``: also report order types missing from the lookup (IDs without
      ``order_type_id``; with ``verify`` they cannot be verified and are reported unverified).
    - ``rectify``: read a foreshortened candidate that failed after its quad was found again
      in a fronto-parallel, upsampled view of its data area (:mod:`~ottag_db.decode.rectify`;
      the points are identified and verified in frame pixels as usual);
      ``rectify_max_ratio``: only quads foreshortened to at most this ratio are retried (see
      :func:`~ottag_db.decode.quads.squeeze`; 0.5: a tilt beyond about 60°);
      ``layout_check_ratio``: on quads foreshortened to at most this ratio whose side along the
      foreshortened direction (:func:`~ottag_db.decode.quads.thinnest_side`) is under
      ``print_check_side_px``, the detected triangles must be a stored layout of the ID (when
      the lookup has layouts): so few pixels across the slivers can lose a vertex at a tip and
      leave a set that fits another order type within the bound (8-point tags read as 6 or 7
      points at 82–85°); the points must then also lie where the stored placement prints them
      (:mod:`~ottag_db.decode.placement_check`), which catches readings with lost vertices whose
      triangles do match (0: never checked). Elsewhere tags drawn by other programs (other
      triangles, another placement) read, unless their points fit only along their side lines
      (each farther than the bound from where the fit puts it): then layout and placement are
      checked at any view (an inverted 8-point tag 70 px wide at 53° that lost a sliver tip read
      as a 7-point type with its points 1.8–2.7 px off the fit, bound 1.5 px);
      ``print_check_side_px``: both checks also apply to data areas whose side
      (``sqrt(area)``) is under this, px: at 21–24 px wide, 8-point tags with a vertex lost in
      a blurred corner read as 6- or 7-point types at full margin (benchmarks/decode_sweeps.py,
      6–7 m, issue 13), and 8-point tags of side 49–61 px at 43–48° whose two triangles
      merged read as 7-point types, their points within the bound (3 wrong IDs in 1,800
      frames of the benchmarks/soft_decoding.py scenes, seeds 2–7, soft decoding off); with the
      checks at every size those frames read the same tags and none of the three; 0 turns this
      off (see
      :func:`~ottag_db.decode.quads.shows_print`);

    Soft decoding (with ``verify``; :mod:`ottag_db.decode.soft`) of a reading below
    ``min_margin_px``:

    - ``soft_max_flips``: the reading and every reading with up to this many of its ambiguous
      triples (a point nearer than ``min_margin_px`` to the line of the other two) reversed
      are looked up and verified (0: no soft decoding, such readings are rejected
      ``low_margin``); 2 because a point near the crossing of two lines makes two triples
      ambiguous at once, and the truth must be among the candidates for the rule to be safe;
    - ``soft_max_triples``: with more ambiguous triples the reading is rejected ``low_margin``
      (6 gives at most 1 + 6 + 15 candidates; more near-collinear triples mean the points
      are too close to call, and more than two flips may be wrong);
    - ``soft_min_fit_gap``: a candidate is accepted only when it alone verifies and its fit
      error is below every other candidate's, and below the reprojection bound, by at least
      this fraction of the bound (see the value's comment).

    Reading by model (:mod:`ottag_db.decode.model_match`), the last resort for a foreshortened
    candidate (``rectify_max_ratio``) or a small one (``model_max_side_px``) that no reading
    decoded:

    - ``model_match``: choose among the lookup's printed tags (stored realization, layout and
      placement) by projecting each through the quad and aligning the best to the image;
    - ``model_max_side_px``: data areas whose side (``sqrt(area)``) is under this, px, are
      read by model at any view (at 6–8 m, 21 cm tags are 18–24 px wide; at 3.5–4 m, 37–42
      px; an inverted tag at 6 m can show only its dark quiet zone's outline, 36 px, its dark
      triangles blurred into it). Up from 32 px: benchmarks/decode_sweeps.py --paired (200
      scenes) read the 10 normal tags it missed at 3.5 and 4 m and the 16 inverted ones at
      6 m, with no look-alike at 3–8 m and the clutter sets' model stage as before;
    - ``model_min_correlation``: the aligned tag's correlation with the image (both inside the
      data area; the tag drawn into the frame with a camera's blur) must reach this;
    - ``model_min_gap``: … and exceed by this every other refined tag's that also stays within
      the misfit limit (a rival with a misfit patch is explained away);
    - ``model_max_misfit``: … and nowhere misfit the image by more than this (the mean absolute
      residual over a tenth of the data area, in units of the tag's contrast, with the frame's
      own blur: the camera blur that fits the tag's outline best, where every tag looks the
      same). Measured on grazing frames (82–86°, benchmarks/decode_sweeps.py scenes at 1.5 m,
      600 frames, complete k ≤ 8 lookup): the correct tag, once aligned with ρ ≥ 0.92,
      misfits by 0.13 (median; 99th percentile 0.25); with the frame's tag removed from the
      lookup (a tag not in a dictionary), no other tag with ρ ≥ 0.92 misfit by less than 0.24.
      Down from 0.28 with one fixed blur (σ 0.45 px), under which the correct tag in a blurrier
      frame misfit like a look-alike (normal tags at 84° 3 points behind inverted ones) and
      rivals of the tag seen fit within the limit only by that blur (steep small tags of
      benchmarks/soft_decoding.py, complete lookup: 138 → 146 of 200 read, 0 wrong);
    - ``model_max_quiet_misfit``: … and the band of quiet zone around the data area must be as
      bright (a normal tag) or as dark (an inverted one) as the aligned tag's print, to this
      mean absolute residual (the scale and offset fitted inside the data area, in units of the
      tag's contrast); a rival that misses it is explained away too. Correlation and misfit
      are judged inside the data area, where a dark data area nearly edge-on can also pass for
      the inside of an inverted tag's quiet zone. Measured on the same 480 frames: the correct
      tag, once aligned, 0.05 (median) and at most 0.20. (The inverted reading of a normal tag
      at 84° that once fit within the other limits, ρ 0.94 and 0.51 here, came from an ECC
      alignment that put part of its data area beyond the horizon, no view at all, now refused
      by the alignment itself);
    - ``model_misfit_lead``: a rival's misfit explains it away only when it also exceeds the
      winner's by this: on the tilt sweep at 86° a look-alike read an inverted tag's thin
      quad with ρ 0.93 and a misfit of 0.275, its rivals (ρ 0.91 and 0.88) explained away by
      misfits of 0.295 and 0.307 (with the fixed blur); up from 0.05 with the lower misfit
      limit: a normal tag at 79° of the tests' grazing frames, its order type missing from the
      lookup, read as an inverted look-alike with ρ 0.927 and a misfit of 0.219, its rival
      (ρ 0.923) explained away by a misfit of 0.274 (steep small tags of
      benchmarks/soft_decoding.py read as with 0.05);
    - ``model_max_templates``: a lookup with more printed tags than this is not read by model
      (the templates take ``4 · 32²`` bytes each, built with the detector);
    - ``model_max_reads``: readings by model per candidate pass (binarization), given to the
      candidates whose coarse match looks most like a printed tag
      (:mod:`ottag_db.decode.model_budget`; the others are rejected with their first reason,
      saying so). Each reading costs 10–40 ms of ECC alignments, and a frame of brick, text
      or foliage can hold dozens of dark quads that no other reading decodes. Per pass, not
      per frame: a later pass outlines only what earlier ones did not, so a tag's better
      outline competes there with few others; on frames holding a tag at 84–86° among 20
      dark quads with a bright blob each (which match printed tags better than the tag's first
      outline does), a budget of 4 per frame lost 7 of 10 tags, 1 per pass none. 2 reads as
      many of 300 frames of one tag at 78–86° as no budget (292, none wrong), and bounds a
      frame to 8 readings (the last two passes run only on a frame that read nothing).

    Hidden borders: ``outline_by_lines`` outlines a candidate whose outline is no quad, or whose
    quad reaches the frame's edge, by the lines of its visible sides
    (:mod:`~ottag_db.decode.candidates`); False reads only tags whose whole outline is seen.

    Raises :class:`~ottag_db.errors.UsageError` for invalid settings.
    """

    use_otsu: bool = True
    use_adaptive: bool = True
    otsu_always: bool = False
    adaptive_block: int = 0
    adaptive_c: float = 7.0
    polarities: tuple[Polarity, ...] = POLARITIES
    min_quad_area_px: float = 256.0
    min_quad_side_px: float = 12.0
    max_candidates: int = 64
    last_resort_passes: bool = True
    min_contrast: float = 20.0
    min_triangle_area_px: float = 6.0
    merge_radius_px: float = 1.0
    merge_radius_rel: float = 0.006
    min_margin_px: float = 1.0
    verify: bool = True
    max_reproj_px: float = 1.5
    max_reproj_rel: float = 0.02
    check_quad: bool = True
    max_quad_error: float = 0.25
    allow_unknown: bool = False
    rectify: bool = True
    rectify_max_ratio: float = 0.5
    layout_check_ratio: float = 0.5
    print_check_side_px: float = 64.0
    soft_max_flips: int = 2
    soft_max_triples: int = 6
    #: 0.35 of the bound (0.53 px at the 1.5 px floor, 2–5 times the 0.1–0.3 px vertex noise).
    #: Measured on small tilted tags (the scenes of benchmarks/soft_decoding.py, 2 × 700 frames,
    #: complete lookup and a D = 3 dictionary): with no lead the rule accepted 1 wrong ID among
    #: 217 soft decodings; another 600 frames gave one wrong ID at a lead of 0.29 (an 8-point tag
    #: that lost two vertices, read as 6 points, a lone candidate fitting at 0.71 of the bound);
    #: 0.35 keeps 202 of the 216 correct ones.
    soft_min_fit_gap: float = 0.35
    model_match: bool = True
    model_max_side_px: float = 48.0
    model_min_correlation: float = 0.92
    model_min_gap: float = 0.08
    model_max_misfit: float = 0.24
    model_max_quiet_misfit: float = 0.3
    model_misfit_lead: float = 0.08
    model_max_templates: int = 20_000
    model_max_reads: int = 2
    outline_by_lines: bool = True

    def __post_init__(self) -> None:
        pols: Any = self.polarities
        # one polarity name, or any iterable of names, is kept as a tuple (the field's type)
        object.__setattr__(self, "polarities", (pols,) if isinstance(pols, str) else tuple(pols))
        if self.adaptive_block and (self.adaptive_block < 3 or self.adaptive_block % 2 == 0):
            raise UsageError(f"adaptive_block must be 0 or an odd number >= 3, got {self.adaptive_block}")
        for p in self.polarities:
            if p not in POLARITIES:
                raise UsageError(f"unknown polarity {p!r}: use 'normal' and/or 'inverted'")
        if not (self.use_otsu or self.use_adaptive):
            raise UsageError("at least one of use_otsu and use_adaptive must be True")
        for name in (
            "min_quad_area_px", "min_quad_side_px", "min_margin_px", "max_reproj_px",
            "soft_max_flips", "soft_max_triples", "soft_min_fit_gap", "model_misfit_lead", "model_max_reads",
        ):  # fmt: skip
            if float(getattr(self, name)) < 0:
                raise UsageError(f"{name} must not be negative")
