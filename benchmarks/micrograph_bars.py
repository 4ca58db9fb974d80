"""The scale bar search of qdots measure on 254 real pictures: found on the drawn bar, found elsewhere, missed.

`benchmarks.micrograph_real` scores the scale read on its pictures against the file's or a hand-measured bar. This one
asks a simpler question of many more, the pictures of the EMPS data set (`benchmarks.micrograph_emps`): is the bar the
search finds (``qdots.micrograph.annotations.find_annotations``) the bar drawn on the picture? The manifest,
``benchmarks/micrograph_bars.toml``, holds each picture's drawn bar, boxed by eye, or none. A bar found elsewhere is
the worst outcome: a user who gives its length (``--scale-bar``) gets a wrong scale without a word; a bar not found
makes the command ask for the scale.

The manifest holds three batches of EMPS pictures, each split into development and test halves before the search was
changed for it: the 134 of `benchmarks.micrograph_emps`, 80 more (``batch = 2``) that no other benchmark uses, and 40
more (``batch = 3``), annotated after the last change for the second and measured once, both halves: how the search
does on pictures it was never shaped on.

Run: ``python -m benchmarks.micrograph_bars [--half dev|test|all] [--fetch [--from DIR]]`` (the first batch is fetched
by ``python -m benchmarks.micrograph_emps --fetch``, the second and third by ``--fetch`` here; ``--from``: a clone of
the EMPS repository).
"""

from __future__ import annotations

import argparse
import time
from collections import Counter
from pathlib import Path

from .micrograph_emps import folder
from .micrograph_emps import manifest as emps_manifest
from .real_data import fetch_one
from .report import Headline, Note, Table, cli_with_options

MEASURED_CODE = ("qdots/micrograph/annotations.py", "qdots/micrograph/bar.py", "qdots/micrograph/scale.py",
                 "qdots/micrograph/colour_bars.py", "qdots/micrograph/bar_profile.py", "qdots/micrograph/strip_bars.py",
                 "qdots/micrograph/film_lines.py", "qdots/micrograph/read.py")
MANIFEST = Path(__file__).with_name("micrograph_bars.toml")
#: A bar found is the drawn one when the middle of its box lies within the drawn bar's box grown by SLACK px, and it is
#: at least COVER of the drawn bar's width (not a piece of it).
SLACK, COVER = 3, 0.8
#: Verdicts, in table order.
VERDICTS = ("on the bar", "elsewhere", "not found", "none drawn, none found", "none drawn, one found")


def manifest() -> list[dict]:
    """The manifest's ``image`` entries."""
    try:
        import tomllib
    except ImportError:  # Python 3.10
        import tomli as tomllib
    with open(MANIFEST, "rb") as f:
        return tomllib.load(f)["image"]


def fetch(source: Path | None = None) -> list[tuple[str, str]]:
    """Fetch the second and third batches' pictures into the EMPS cache folder (from ``source``, a clone of the EMPS repository, or
    its pinned commit on GitHub), each checked against the manifest's sha256; returns (file, what was done or the
    error)."""
    base = emps_manifest()["source"]["images"]
    target = folder()
    target.mkdir(parents=True, exist_ok=True)
    done = []
    for e in manifest():
        if "sha256" not in e:
            continue
        try:
            done.append((e["file"], fetch_one(e["file"], base + e["file"], e["sha256"], target,
                                              None if source is None else source / "images")))
        except (OSError, ValueError) as exc:
            done.append((e["file"], f"failed: {type(exc).__name__}: {exc}"))
    return done


def verdict(drawn: list[int] | None, found: tuple[int, int, int, int] | None) -> str:
    """One of `VERDICTS` for the bar ``drawn`` (a box, or None) and the box ``found`` (or None)."""
    if drawn is None:
        return VERDICTS[3] if found is None else VERDICTS[4]
    if found is None:
        return VERDICTS[2]
    x0, y0, x1, y1 = drawn
    middle = (0.5 * (found[0] + found[2]), 0.5 * (found[1] + found[3]))
    inside = x0 - SLACK <= middle[0] <= x1 + SLACK and y0 - SLACK <= middle[1] <= y1 + SLACK
    return VERDICTS[0] if inside and found[2] - found[0] >= COVER * (x1 - x0) else VERDICTS[1]


def measure_entry(entry: dict) -> dict:
    from qdots.micrograph.annotations import find_annotations
    from qdots.micrograph.read import read_micrograph
    from qdots.micrograph.scale import shortest_bar

    start = time.perf_counter()
    image = read_micrograph(folder() / entry["file"])
    bar = find_annotations(image.pixels.astype(float)).bar
    drawn = entry.get("bar")
    short = drawn is not None and drawn[2] - drawn[0] < shortest_bar(image.shape)
    return {"file": entry["file"], "half": entry["half"], "batch": entry.get("batch", 1), "drawn": entry["drawn"],
            "box": drawn,
            "found": None if bar is None else bar.box, "length": None if bar is None else bar.length_px,
            "verdict": verdict(drawn, None if bar is None else bar.box), "short": short,
            "seconds": time.perf_counter() - start}


def tables(rows: list[dict], half: str) -> list:
    """The summary and the misses of one half of one batch (``half``: its name in the tables' titles)."""
    counts = Counter(r["verdict"] for r in rows)
    drawn = sum(r["box"] is not None for r in rows)
    short = sum(r["short"] and r["verdict"] == VERDICTS[2] for r in rows)
    summary = Table(f"Scale bars on the EMPS pictures, {half}: the bar found against the bar drawn",
                    ["pictures", "bars drawn", *VERDICTS[:3], "of those not found: under a twentieth of the picture",
                     "no bar drawn", *VERDICTS[3:]],
                    [[len(rows), drawn, *(counts[v] for v in VERDICTS[:3]), short, len(rows) - drawn,
                      *(counts[v] for v in VERDICTS[3:])]])
    misses = [r for r in rows if r["verdict"] not in (VERDICTS[0], VERDICTS[3])]
    detail = Table(f"Scale bars on the EMPS pictures, {half}: the pictures where the bar found is not the one drawn",
                   ["picture", "drawn", "drawn at (x0, y0, x1, y1)", "found at", "found length (px)", "verdict"],
                   [[r["file"], r["drawn"] + (" (under a twentieth of the picture)" if r["short"] else ""),
                     "" if r["box"] is None else str(tuple(r["box"])), "" if r["found"] is None else str(r["found"]),
                     "" if r["length"] is None else f"{r['length']:.1f}", r["verdict"]] for r in misses])
    return [summary, detail]


def results(halves: tuple[str, ...]) -> list:
    chosen = [e for e in manifest() if e["half"] in halves]
    missing = [e for e in chosen if not (folder() / e["file"]).exists()]
    if missing:
        second = sum("sha256" in e for e in missing)
        return [Note(f"{len(missing)} of the {len(chosen)} EMPS pictures are not in {folder()} (the cache folder): "
                     "fetch them with `python -m benchmarks.micrograph_emps --fetch`"
                     + (f" ({len(missing) - second}) and `python -m benchmarks.micrograph_bars --fetch` ({second})."
                        if second else "."))]
    rows = [measure_entry(e) for e in chosen]
    out: list = []
    summary = []
    for batch in (1, 2, 3):
        for half in halves:
            part = [r for r in rows if r["half"] == half and r["batch"] == batch]
            if not part:
                continue
            name = f"{half} half" + ("", " of the second batch", " of the third batch")[batch - 1]
            out += tables(part, name)
            counts = Counter(r["verdict"] for r in part)
            drawn = sum(r["box"] is not None for r in part)
            summary.append(f"{half}{'' if batch == 1 else f' {batch}'}: {counts[VERDICTS[0]]} of {drawn} drawn bars found, "
                           f"{counts[VERDICTS[1]]} found elsewhere, {counts[VERDICTS[4]]} found where none is drawn")
    seconds = sum(r["seconds"] for r in rows)
    out.insert(0, Headline(f"qdots measure's scale bar search on {len(rows)} EMPS pictures (dev / test halves, three "
                           "batches)",
                           f"{seconds:.0f} s for {len(rows)} pictures", "; ".join(summary)))
    out.append(Note("The bar found is the drawn one when the middle of its box lies within the drawn bar's box (boxed by "
                    f"eye, grown by {SLACK} px) and it is at least {COVER:g} of its width. A bar under a twentieth of the "
                    "picture's longer side is not sought (`qdots.micrograph.scale.MIN_BAR_SHARE`). Lengths are scored "
                    "against bars measured by hand in `micrograph_real`."))
    return out


def run(quick: bool) -> list:
    """Both halves (quick: the development half)."""
    return results(("dev",) if quick else ("dev", "test"))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--half", choices=("dev", "test", "all"), default="all")
    parser.add_argument("--fetch", action="store_true",
                        help="download the second and third batches' pictures into the cache first")
    parser.add_argument("--from", dest="source", type=Path, default=None,
                        help="with --fetch: copy them from a clone of the EMPS repository instead")

    def make(args):
        if args.fetch:
            for name, what in fetch(source=args.source):
                print(f"{name}: {what}")
        return results(("dev", "test") if args.half == "all" else (args.half,))

    return cli_with_options(parser, make, argv)


if __name__ == "__main__":
    raise SystemExit(main())
