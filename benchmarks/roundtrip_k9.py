"""Round trip of nine-point tags: point file → database → PDF sheet → raster pages → decoder.

Imports a nine-point file (with mirrors) into a fresh temporary database (or uses ``--db``),
exports one sheet of ``--tags`` tags — the ``--top`` highest-MP order types plus a seeded
random sample of the rest — rasterizes every page with pdfium (grey, anti-aliased, no blur or
noise) and decodes it with a detector loaded from the same database. A tag counts as decoded
when its own ID is read on its own page in its polarity; any other reading on a page (an ID
not printed there, or one printed ID read twice) is a wrong ID. Prints decoded/total, wrong
IDs, the tags whose printed margin is under the decoder's threshold at that resolution, and
the time of each step.

The sheet is what ``ottag-db export`` writes by default (packed, no cut marks; 40 mm tags:
12 per A4 page).

    python benchmarks/roundtrip_k9.py [--file data/ottag-k09.b08] [--tags 2000] [--dpi 300]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path

import numpy as np

from ottag_db.app.detector import open_detector
from ottag_db.app.export import TagFilter, export_sheet, select_for_export
from ottag_db.printing.sheet import SheetOptions
from ottag_db.store.db import open_database
from ottag_db.store.importer import import_point_file
from ottag_db.store.tags import TagRecord

#: The decoder rejects readings under ``min_margin_px`` = 1 px; tags whose printed margin
#: (2 × printed MP) is under this at the chosen resolution are reported separately.
MIN_MARGIN_PX = 1.5


def choose_tags(tags: list[TagRecord], total: int, top: int, seed: int) -> list[TagRecord]:
    """The ``top`` highest-MP tags plus a seeded random sample of the others, ``total`` in all."""
    by_mp = sorted(tags, key=lambda t: (-t.mp, t.lambda_text))
    best = by_mp[:top]
    rest = by_mp[top:]
    rng = np.random.default_rng(seed)
    pick = rng.choice(len(rest), size=min(len(rest), max(0, total - len(best))), replace=False)
    return best + [rest[int(i)] for i in sorted(pick)]


def main(argv: list[str] | None = None) -> int:
    """Run the round trip and print the figures; exit 1 when a tag is missed or misread."""
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument(
        "--file",
        type=Path,
        default=Path(__file__).resolve().parents[1] / "data" / "ottag-k09.b08",
        help="nine-point file",
    )
    parser.add_argument("--db", type=Path, default=None, help="use this database (k = 9 already imported)")
    parser.add_argument("--tags", type=int, default=2000, help="tags on the sheet")
    parser.add_argument("--top", type=int, default=1000, help="of which the highest-MP ones")
    parser.add_argument("--seed", type=int, default=9)
    parser.add_argument("--dpi", type=int, default=300)
    parser.add_argument("--tag-size", type=float, default=40.0, help="data-area side, mm")
    parser.add_argument("--polarity", choices=("normal", "inverted"), default="normal")
    parser.add_argument("--pages", type=int, default=None, help="decode only the first N pages")
    parser.add_argument("--cut-marks", action="store_true", help="keep each quiet zone whole (no packing)")
    args = parser.parse_args(argv)
    import pypdfium2 as pdfium  # test extra; imported here so --help works without it

    with tempfile.TemporaryDirectory() as tmp:
        db_path = args.db
        t0 = time.perf_counter()
        if db_path is None:
            db_path = Path(tmp) / "k9.sqlite"
            db = open_database(db_path)
            rep = import_point_file(db, args.file, n=9, with_mirrors=True)
            print(f"import: {rep.records} records, {rep.new_order_types} order types, {rep.seconds:.1f} s")
        else:
            db = open_database(db_path)
        try:
            chosen = choose_tags(select_for_export(db, TagFilter(ks=(9,))), args.tags, args.top, args.seed)
            flt = TagFilter(ids=tuple(t.lambda_text for t in chosen))
            tags = select_for_export(db, flt)  # the sheet's own order
            pdf = Path(tmp) / "k9.pdf"
            sheet = export_sheet(
                db, pdf, flt, SheetOptions(tag_size_mm=args.tag_size, cut_marks=args.cut_marks), polarity=args.polarity
            )
        finally:
            db.close()
        print(f"export: {sheet.tags} tags on {sheet.pages} pages ({sheet.per_page} per page), {sheet.seconds:.1f} s")
        det = open_detector(str(db_path))
        size_px = sheet.tag_size_mm * args.dpi / 25.4
        decoded = wrong = checked = 0
        excused: list[str] = []
        missing: list[str] = []
        t_raster = t_decode = 0.0
        doc = pdfium.PdfDocument(str(pdf))
        try:
            pages = len(doc) if args.pages is None else min(args.pages, len(doc))
            for page_no in range(pages):
                t1 = time.perf_counter()
                page = doc[page_no]
                img = page.render(scale=args.dpi / 72.0, grayscale=True).to_numpy()
                page.close()
                if img.ndim == 3:
                    img = img[:, :, 0]
                t2 = time.perf_counter()
                dets = det.detect(np.ascontiguousarray(img))
                t_decode += time.perf_counter() - t2
                t_raster += t2 - t1
                expected = tags[page_no * sheet.per_page : (page_no + 1) * sheet.per_page]
                want = {t.lambda_text: t for t in expected}
                seen = Counter(d.lambda_text for d in dets if d.polarity == args.polarity)
                wrong += sum(1 for d in dets if d.lambda_text not in want or d.polarity != args.polarity)
                wrong += sum(n - 1 for text, n in seen.items() if text in want and n > 1)
                for t in expected:
                    checked += 1
                    if seen.get(t.lambda_text):
                        decoded += 1
                    elif 2 * t.printed_mp_unit * size_px < MIN_MARGIN_PX:
                        excused.append(t.lambda_text)
                    else:
                        missing.append(f"page {page_no + 1}: #{t.order_type_id} MP {t.mp:.2f} {t.lambda_text}")
                print(
                    f"\rpage {page_no + 1}/{pages}: decoded {decoded}/{checked}, wrong {wrong}", end="", file=sys.stderr
                )
        finally:
            doc.close()
        print(file=sys.stderr)
    mps = np.array([t.mp for t in tags])
    print(
        f"k = 9 round trip at {args.dpi} dpi ({args.polarity}, {sheet.tag_size_mm:g} mm tags, data area "
        f"{size_px:.0f} px; MP {mps.min():.2f} … {mps.max():.2f} grid units): decoded {decoded}/{checked}, "
        f"wrong IDs {wrong}, missing {len(missing)}, printed margin under {MIN_MARGIN_PX} px: {len(excused)}"
    )
    print(
        f"time: rasterize {t_raster:.1f} s, decode {t_decode:.1f} s ({1000 * t_decode / max(pages, 1):.0f} ms/page), "
        f"total {time.perf_counter() - t0:.1f} s"
    )
    for line in missing[:20]:
        print("  missing", line)
    return 0 if wrong == 0 and not missing else 1


if __name__ == "__main__":
    raise SystemExit(main())
