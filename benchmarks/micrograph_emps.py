"""qdots measure on 134 labelled films of the EMPS data set: films of round particles measured, other shapes refused.

`benchmarks.micrograph_real` scores 40 pictures in depth (scale, sizes, sigma against each one's reference). This
one asks one question of many more: does ``qdots measure`` take a film of round particles and refuse a picture of
other shapes, as a user meets them? The EMPS data set (Yildirim and Cole 2021: 465 electron micrographs, crops of
published figures, each with hand-drawn instance labels) is read by its own labels: a picture whose labelled
particles are clearly round is a film to measure, one whose particles are clearly elongated or not convex is one to
refuse (`stratum`; the manifest, ``benchmarks/micrograph_emps.toml``, says which pictures, and holds the
development / test split made before any code was changed for them). Each picture is measured as a user would
(``measure_image``, no scale, no option); a measured film's median diameter is set beside the median
area-equivalent diameter of its labels (outlines drawn on the outer boundary, 5-17 % outside the half-depth edge on
the pictures of `benchmarks.micrograph_real`), and the number of whole dots beside the number of labels (the
labels need not hold every particle).

Run: ``python -m benchmarks.micrograph_emps [--fetch [--from DIR]] [--half dev|test|all] [--jobs N]`` (``--from``:
a clone of the EMPS repository; without the pictures in the cache it says how to fetch them).
"""

from __future__ import annotations

import argparse
import math
import time
from collections import Counter
from pathlib import Path

import numpy as np

from .real_data import cache_folder, fetch_one
from .report import Headline, Note, Table, cli_with_options

MEASURED_CODE = ("qdots/micrograph",)
MANIFEST = Path(__file__).with_name("micrograph_emps.toml")
#: The strata read off a picture's labels (`label_shapes`): at least MIN_PARTICLES whole particles (not touching the
#: edge, MIN_AREA px or more); round where their median axis ratio is at most ROUND_ASPECT and their median solidity
#: (area over convex hull) at least ROUND_SOLIDITY; not round where the axis ratio is at least OTHER_ASPECT or the
#: solidity at most OTHER_SOLIDITY; neither (not in the manifest) between.
MIN_PARTICLES, MIN_AREA = 10, 20
ROUND_ASPECT, ROUND_SOLIDITY, OTHER_ASPECT, OTHER_SOLIDITY = 1.2, 0.93, 1.5, 0.85
#: Pictures measured side by side in the full run (processes): its times are each picture's with another running.
JOBS = 2


def manifest() -> dict:
    """The manifest: its ``source`` table and its ``image`` entries."""
    try:
        import tomllib
    except ImportError:  # Python 3.10
        import tomli as tomllib
    with open(MANIFEST, "rb") as f:
        return tomllib.load(f)


def folder() -> Path:
    """Where the pictures and their labels are fetched: ``emps/`` in `benchmarks.real_data.cache_folder`."""
    return cache_folder() / "emps"


def labels_name(file: str) -> str:
    return file.replace(".png", "_labels.png")


def fetch(source: Path | None = None) -> list[tuple[str, str]]:
    """Fetch every picture and its labels (from ``source``, a clone of the EMPS repository, or its pinned commit on
    GitHub), each checked against the manifest's sha256; returns (file, what was done or the error)."""
    table = manifest()
    target = folder()
    target.mkdir(parents=True, exist_ok=True)
    done = []
    for e in table["image"]:
        for name, sub, base, digest in ((e["file"], "images", table["source"]["images"], e["sha256"]),
                                        (labels_name(e["file"]), "segmaps", table["source"]["labels"],
                                         e["labels_sha256"])):
            try:
                done.append((name, fetch_one(name, base + e["file"], digest, target,
                                             None if source is None else source / sub, source_name=e["file"])))
            except (OSError, ValueError) as exc:
                done.append((name, f"failed: {type(exc).__name__}: {exc}"))
    return done


def label_shapes(labels: np.ndarray) -> dict:
    """A label image's whole particles (1 .. n, not touching the edge, `MIN_AREA` px or more): their number, median
    area-equivalent diameter (px), median axis ratio (from the second moments) and median solidity."""
    from skimage.measure import regionprops

    labels = np.asarray(labels)
    labels = labels[..., 0] if labels.ndim == 3 else labels
    h, w = labels.shape
    whole = [p for p in regionprops(labels.astype(np.int32)) if p.area >= MIN_AREA
             and p.bbox[0] > 0 and p.bbox[1] > 0 and p.bbox[2] < h and p.bbox[3] < w]
    if not whole:
        return {"particles": 0, "diameter": math.nan, "aspect": math.nan, "solidity": math.nan}
    return {"particles": len(whole),
            "diameter": float(np.median([p.equivalent_diameter_area for p in whole])),
            "aspect": float(np.median([p.axis_major_length / max(p.axis_minor_length, 1e-9) for p in whole])),
            "solidity": float(np.median([p.solidity for p in whole]))}


def stratum(shapes: dict) -> str | None:
    """``"round"``, ``"not round"`` or None (neither clearly; too few particles), from `label_shapes`."""
    if shapes["particles"] < MIN_PARTICLES:
        return None
    if shapes["aspect"] <= ROUND_ASPECT and shapes["solidity"] >= ROUND_SOLIDITY:
        return "round"
    if shapes["aspect"] >= OTHER_ASPECT or shapes["solidity"] <= OTHER_SOLIDITY:
        return "not round"
    return None


def reason(message: str) -> str:
    """A refusal's reason in a few words (the first of `qdots.micrograph.admit.film_verdict`'s)."""
    for key, short in (("outlines wander", "outlines not round"), ("elongated", "elongated"),
                       ("stand out of the background", "under 10 whole dots"), ("lie in lines", "in lines (text)"),
                       ("closer than", "pieces of larger objects"), ("px across", "dots under 5 px"),
                       ("flat colour", "flat colour (a drawing)"), ("no dots found", "no dots found")):
        if key in message:
            return short
    return message[:60]


def measure_entry(entry: dict) -> dict:
    """Measure one picture as a user would and read its labels (see the module)."""
    from PIL import Image

    from labrig.validate import InputError
    from qdots.micrograph.admit import NotAFilm
    from qdots.micrograph.measure import measure_image

    path = folder() / entry["file"]
    with Image.open(folder() / labels_name(entry["file"])) as labels:
        shapes = label_shapes(np.array(labels))
    row = {"file": entry["file"], "half": entry["half"], "stratum": entry["stratum"], **shapes}
    start = time.perf_counter()
    try:
        film = measure_image(path, lqe=False)
        row["verdict"] = "measured"
    except NotAFilm as exc:
        row.update(verdict="refused", why=reason(str(exc)))
        film = exc.found
    except InputError as exc:
        row.update(verdict="refused", why=reason(str(exc)))
        film = None
    row["seconds"] = time.perf_counter() - start
    if film is not None:
        whole = ~film.detection.cut
        row["dots"] = int(np.count_nonzero(whole))
        row["d"] = float(np.median(film.detection.diameters[whole])) if whole.any() else math.nan
    return row


def expected(row: dict) -> str:
    return "measured" if row["stratum"] == "round" else "refused"


def tables(rows: list[dict], half: str) -> list:
    """The confusion of strata and verdicts, the refusals' reasons and the measured round films' sizes of one half."""
    count = Counter((r["stratum"], r["verdict"]) for r in rows)
    confusion = Table(f"EMPS films, {half} half: what qdots measure did, by what the labels show",
                      ["labels show", "pictures", "measured", "refused", "as expected"],
                      [[s, sum(count[(s, v)] for v in ("measured", "refused")), count[(s, "measured")],
                        count[(s, "refused")], f"{count[(s, 'measured' if s == 'round' else 'refused')]} of "
                        f"{sum(count[(s, v)] for v in ('measured', 'refused'))}"]
                       for s in ("round", "not round")])
    wrong = [r for r in rows if r["verdict"] != expected(r)]
    detail = Table(f"EMPS films, {half} half: the pictures not handled as their labels say",
                   ["picture", "labels show", "verdict", "why", "labelled particles", "their median d (px)",
                    "their axis ratio", "whole dots found", "their median d (px)", "time (s)"],
                   [[r["file"], r["stratum"], r["verdict"], r.get("why", ""), r["particles"], r["diameter"],
                     r["aspect"], r.get("dots", ""), r.get("d", math.nan), r["seconds"]] for r in wrong])
    measured = [r for r in rows if r["stratum"] == "round" and r["verdict"] == "measured"]
    ratio = np.array([r["d"] / r["diameter"] for r in measured])
    dots = np.array([r["dots"] / r["particles"] for r in measured])
    note = Note(f"{half}: of {len(measured)} round films measured, the median diameter over the labels' ran "
                + (f"{np.min(ratio):.2f}-{np.max(ratio):.2f} (median {np.median(ratio):.2f}; within 0.8-1.1 on "
                   f"{int(np.sum((ratio >= 0.8) & (ratio <= 1.1)))}), and the whole dots over the labels "
                   f"{np.min(dots):.2f}-{np.max(dots):.2f} (median {np.median(dots):.2f})." if measured else "-"))
    return [confusion, detail, note]


def results(halves: tuple[str, ...], most: int | None = None, jobs: int = 1) -> list:
    chosen = [e for e in manifest()["image"] if e["half"] in halves][:most]
    missing = [e["file"] for e in chosen if not (folder() / e["file"]).exists()
               or not (folder() / labels_name(e["file"])).exists()]
    if missing:
        return [Note(f"{len(missing)} of the {len(chosen)} EMPS pictures are not in {folder()} (the cache folder): "
                     "fetch them with `python -m benchmarks.micrograph_emps --fetch`.")]
    if jobs > 1:
        from concurrent.futures import ProcessPoolExecutor

        with ProcessPoolExecutor(jobs) as pool:
            rows = list(pool.map(measure_entry, chosen))
    else:
        rows = [measure_entry(e) for e in chosen]
    out: list = []
    summary = []
    for half in halves:
        part = [r for r in rows if r["half"] == half]
        if not part:
            continue
        out += tables(part, half)
        round_ = [r for r in part if r["stratum"] == "round"]
        other = [r for r in part if r["stratum"] != "round"]
        summary.append(f"{half}: round films measured {sum(r['verdict'] == 'measured' for r in round_)} of "
                       f"{len(round_)}; other shapes refused {sum(r['verdict'] == 'refused' for r in other)} of "
                       f"{len(other)}")
    seconds = [r["seconds"] for r in rows]
    out.insert(0, Headline("qdots measure's verdict on labelled EMPS films (dev / test halves)",
                           f"{sum(seconds):.0f} s for {len(seconds)} pictures (median {np.median(seconds):.1f} s)",
                           "; ".join(summary)))
    return out


def run(quick: bool) -> list:
    """Both halves, two pictures at a time (`JOBS`; quick: the first 3 pictures of the development half, one at a
    time)."""
    return results(("dev",), most=3) if quick else results(("dev", "test"), jobs=JOBS)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--fetch", action="store_true", help="download the pictures and labels into the cache first")
    parser.add_argument("--from", dest="source", type=Path, default=None,
                        help="with --fetch: copy them from a clone of the EMPS repository instead")
    parser.add_argument("--half", choices=("dev", "test", "all"), default="all")
    parser.add_argument("--jobs", type=int, default=1, help="pictures measured side by side (processes)")

    def make(args):
        if args.fetch:
            for name, what in fetch(source=args.source):
                if what != "present":
                    print(f"{name}: {what}")
        return results(("dev", "test") if args.half == "all" else (args.half,), jobs=max(1, args.jobs))

    return cli_with_options(parser, make, argv)


if __name__ == "__main__":
    raise SystemExit(main())
