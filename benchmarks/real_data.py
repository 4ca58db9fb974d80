"""Real micrographs for the benchmarks: the manifest, fetching the files from their sources, and their references.

The pictures are public files that no one on this project made (sources, licences and the dev / test split in
``benchmarks/micrograph_real.toml``). They are not kept in the repository: `fetch` downloads each from its
pinned source into `cache_folder` (``NANODISORDER_REAL_MICROGRAPHS``, default ``~/.cache/nanodisorder/
real-micrographs``) and checks its sha256; ``--from DIR`` copies them from a folder that already holds them.

`reference` turns what a source publishes beside its picture (hand-drawn outlines, boxes, a particle list or a
stated size) into the sizes a measurement is scored against; `half_depth_widths` is the line-profile measurement
by hand, the full width at half depth along a row or a column, written here independently of the package. A size
the source states is the reference; otherwise the particles it outlines, boxes or lists are measured by hand
profiles at their own centres (outlines are drawn along the outer boundary, in defocused TEM the crest of the bright
Fresnel fringe, 5-17 % outside the half-depth edge that line profiles and thresholds find: both are reported).
"""

from __future__ import annotations

import argparse
import hashlib
import io
import os
import shutil
import urllib.request
import zipfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy import ndimage

from labrig.files import atomic_path

MANIFEST = Path(__file__).with_name("micrograph_real.toml")
#: Largest file fetched, bytes (the largest in the manifest is under 4 MiB).
MAX_BYTES = 64 * 2**20
#: A hand line profile seeks the background beyond CREST_INSIDE of the particle's outline radius, where the source
#: outlines its particles (`half_depth_widths`): the gap to a neighbour lies at the outline or beyond (the outlines
#: sit 5-17 % outside the half-depth edge), a particle's own light specks inside it.
CREST_INSIDE = 0.75


def cache_folder() -> Path:
    """Where the fetched pictures live: ``$NANODISORDER_REAL_MICROGRAPHS`` or ``~/.cache/nanodisorder/real-micrographs``."""
    default = Path.home() / ".cache" / "nanodisorder" / "real-micrographs"
    return Path(os.environ.get("NANODISORDER_REAL_MICROGRAPHS", default))


def entries() -> list[dict]:
    """The manifest's entries, in its order."""
    try:
        import tomllib
    except ImportError:  # Python 3.10
        import tomli as tomllib
    with open(MANIFEST, "rb") as f:
        return tomllib.load(f)["image"]


def sha256(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def download(url: str) -> bytes:
    with urllib.request.urlopen(url, timeout=60) as response:  # noqa: S310 (https addresses of the manifest)
        data = response.read(MAX_BYTES + 1)
    if len(data) > MAX_BYTES:
        raise ValueError(f"{url}: more than {MAX_BYTES} bytes")
    return data


def fetch_one(name: str, url: str, digest: str, folder: Path, source: Path | None, member: str | None = None,
              member_digest: str | None = None, source_name: str | None = None) -> str:
    """Put the file ``name`` in ``folder``: copied from ``source`` (a folder; the file ``source_name`` there, default
    ``name``) or downloaded from ``url`` (a zip's ``member`` when given), its sha256 checked. Returns what was done,
    in words."""
    target = folder / name
    if target.exists() and sha256(target.read_bytes()) == digest:
        return "present"
    if source is not None:
        data = (source / (source_name or name)).read_bytes()
    else:
        data = download(url)
        if member is not None:
            if sha256(data) != member_digest:
                raise ValueError(f"{url}: the archive's sha256 is not the manifest's")
            with zipfile.ZipFile(io.BytesIO(data)) as archive:
                data = archive.read(member)
    if sha256(data) != digest:
        raise ValueError(f"{name}: sha256 {sha256(data)[:12]}... is not the manifest's {digest[:12]}...")
    with atomic_path(target) as tmp:
        tmp.write_bytes(data)
    return "copied" if source is not None else "downloaded"


def fetch(folder: Path | None = None, source: Path | None = None) -> list[tuple[str, str]]:
    """Fetch every picture of the manifest and its reference file; returns (file, what was done or the error)."""
    folder = cache_folder() if folder is None else Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    done = []
    for e in entries():
        jobs = [(e["file"], e["url"], e["sha256"], e.get("archive_member"), e.get("archive_sha256"))]
        if "reference_url" in e:
            jobs.append((e["reference_file"], e["reference_url"], e["reference_sha256"], None, None))
        for name, url, digest, member, member_digest in jobs:
            try:
                done.append((name, fetch_one(name, url, digest, folder, source, member, member_digest)))
            except (OSError, ValueError, KeyError, zipfile.BadZipFile) as exc:
                done.append((name, f"failed: {type(exc).__name__}: {exc}"))
    return done


def halves_main(results: Callable[[tuple[str, ...], list[str] | None], list], description: str,
                argv: list[str] | None = None) -> int:
    """A real-micrograph benchmark's ``main``: ``--half dev|test|all`` (default dev) and ``--only ID ...``, then
    ``results(halves, only)`` printed (`benchmarks.report.cli_with_options`)."""
    from .report import cli_with_options

    parser = argparse.ArgumentParser(description=description)
    parser.add_argument("--half", choices=("dev", "test", "all"), default="dev")
    parser.add_argument("--only", nargs="*", default=None, metavar="ID")
    return cli_with_options(parser, lambda args: results(("dev", "test") if args.half == "all" else (args.half,),
                                                          args.only), argv)


def copy_cache(target: Path) -> None:
    """Copy the cache folder to ``target`` (to carry it to another machine)."""
    shutil.copytree(cache_folder(), target, dirs_exist_ok=True)


@dataclass(frozen=True)
class Reference:
    """The sizes a picture is scored against, px.

    ``mean_px`` is the scored mean diameter: a size the source states, else the full width at half depth by hand
    (`half_depth_widths`) of the source's own particles (or of 10 picked by eye). ``spread`` is the scored size
    spread (SD / mean): the source's stated one, else that of its own particles' sizes, else of the hand widths.
    ``source_mean_px`` is the mean of the source's own per-particle sizes (its outlines' area-equivalent
    diameters, its boxes' sides), NaN without them; ``source_spread`` is their spread by the estimator `qdots measure`
    reports (`qdots.micrograph.film.size_spread`: sizes over 4.5 robust deviations left out), where the scored spread
    is one the source states from a fit of its own (NaN otherwise); ``centres`` and ``diameters`` (the source's) are None without
    them; ``widths`` are the hand widths of the particles at ``width_centres`` (NaN where no line served), for a
    comparison particle by particle; ``count`` is how many particles the reference holds and ``how`` says all this
    in words."""

    mean_px: float
    spread: float
    count: int
    how: str
    source_mean_px: float = float("nan")
    diameters: np.ndarray | None = None
    centres: np.ndarray | None = None
    widths: np.ndarray | None = None
    width_centres: np.ndarray | None = None
    source_spread: float = float("nan")


def whole_labels(labels: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Area-equivalent diameters (px) and centroids (x, y) of the labelled regions that do not touch the edge."""
    n = int(labels.max())
    area = np.bincount(labels.ravel(), minlength=n + 1)[1:].astype(float)
    edge = np.unique(np.concatenate([labels[0], labels[-1], labels[:, 0], labels[:, -1]]))
    keep = (area > 0) & ~np.isin(np.arange(1, n + 1), edge)
    rows, cols = np.indices(labels.shape)
    cy = np.bincount(labels.ravel(), rows.ravel(), minlength=n + 1)[1:] / np.maximum(area, 1)
    cx = np.bincount(labels.ravel(), cols.ravel(), minlength=n + 1)[1:] / np.maximum(area, 1)
    centres = np.column_stack([cx + 0.5, cy + 0.5])[keep]
    return 2.0 * np.sqrt(area[keep] / np.pi), centres


def source_particles(entry: dict, folder: Path) -> tuple[np.ndarray, np.ndarray, str] | None:
    """The source's own particles: diameters (px), centres (x, y px) and what they are, or None."""
    from PIL import Image

    kind = entry.get("reference")
    if kind in ("labels", "binary"):
        labels = np.asarray(Image.open(folder / entry["reference_file"]))
        if labels.ndim == 3:
            labels = labels[..., 0]
        if kind == "binary":
            labels = ndimage.label(labels == 0 if entry.get("mask_zero_is_particle") else labels > 0)[0]
        d, c = whole_labels(labels.astype(np.int64))
        return d, c, "hand-drawn outlines" if kind == "labels" else "a published mask"
    if kind in ("boxes", "list"):
        rows = np.loadtxt(folder / entry["reference_file"], comments="#", ndmin=2)
        if kind == "list":  # x, y (px) and the radius (nm) of each particle
            return 2.0 * rows[:, 2] / entry["scale_nm_per_px"], rows[:, :2], "a published particle list"
        with Image.open(folder / entry["file"]) as im:
            w, h = im.size
        cx, cy, bw, bh = rows[:, 1] * w, rows[:, 2] * h, rows[:, 3] * w, rows[:, 4] * h
        inside = (cx - bw / 2 > 1) & (cy - bh / 2 > 1) & (cx + bw / 2 < w - 1) & (cy + bh / 2 < h - 1)
        return (0.5 * (bw + bh))[inside], np.column_stack([cx, cy])[inside], "published boxes"
    return None


def reference(entry: dict, folder: Path | None = None) -> Reference | None:
    """The reference sizes of a manifest entry (see `Reference`); None for a picture that is to be refused, or where
    none could be taken."""
    from qdots.micrograph.read import read_micrograph

    folder = cache_folder() if folder is None else Path(folder)
    kind = entry.get("reference")
    if kind in (None, "none"):
        return None
    dark = entry.get("polarity", "dark") == "dark"
    if "reference_diameter_nm" in entry:  # a size the source states
        scale = entry["scale_nm_per_px"]
        own = source_particles(entry, folder)
        from qdots.micrograph.film import size_spread

        return Reference(entry["reference_diameter_nm"] / scale, entry["reference_sd_nm"] / entry["reference_diameter_nm"],
                         len(own[0]) if own else 0, "the size the source states",
                         float(own[0].mean()) if own else float("nan"), *(own[:2] if own else (None, None)),
                         source_spread=size_spread(own[0])["size_spread"] if own else float("nan"))
    image = read_micrograph(folder / entry["file"]).pixels
    if kind == "profiles":
        centres = np.asarray(entry["profile_centres"], dtype=float)
        widths = half_depth_widths(image, centres, dark, entry["profile_reach"])
        d = widths[np.isfinite(widths)]
        return Reference(float(d.mean()), float(d.std(ddof=1) / d.mean()), len(d),
                         f"hand line profiles of {len(d)} particles picked by eye", widths=widths,
                         width_centres=centres)
    diameters, centres, what = source_particles(entry, folder)
    if entry.get("reference_measure") == "source":
        return Reference(float(diameters.mean()), float(diameters.std(ddof=1) / diameters.mean()), len(diameters),
                         f"its {what}", float(diameters.mean()), diameters, centres)
    widths = half_depth_widths(image, centres, dark, 1.5 * float(np.median(diameters)) / 2 + 3,
                               CREST_INSIDE * diameters / 2)
    ok = np.isfinite(widths)
    return Reference(float(widths[ok].mean()), float(diameters.std(ddof=1) / diameters.mean()), len(diameters),
                     f"hand line profiles of {int(ok.sum())} of its particles; sigma of its {what}",
                     float(diameters.mean()), diameters, centres, widths, centres)


def half_depth_widths(image: np.ndarray, centres: np.ndarray, dark: bool, reach: float,
                      inner: np.ndarray | None = None) -> np.ndarray:
    """The full width at half depth of the particles at ``centres`` (x, y, px), along the row and the column through
    each (their mean; a line whose two sides do not reach the same background, a neighbour or a slope, is not used),
    as one measures by hand: on the image smoothed by 1 px, the core is the 10th percentile of the line's middle
    half (dark particles; the 90th for light ones), the background on each side the lightest value (the darkest)
    between the middle and ``reach`` px out (the plateau, or the crest of the gap to the next particle), and the
    width runs between the crossings of the half-way level, interpolated linearly. NaN where neither line serves.

    ``inner`` (px, one per particle; `CREST_INSIDE` of its outline's radius where the source outlines it): no crest
    is sought nearer the middle than that, as one reads the background by hand: a textured particle's own light
    specks are not its background."""
    smooth = ndimage.gaussian_filter(np.asarray(image, dtype=float), 1.0)
    v = smooth if dark else -smooth  # particles are low in v
    h, w = v.shape
    r = int(round(reach))
    out = np.full(len(centres), np.nan)
    for k, (x, y) in enumerate(centres):
        row, col = int(y), int(x)
        if not (r <= row < h - r and r <= col < w - r):
            continue
        skip = 0 if inner is None else min(r - 1, int(inner[k]))  # px next to the middle where no crest is sought
        widths = []
        for profile in (v[row, col - r:col + r + 1], v[row - r:row + r + 1, col]):
            core = float(np.percentile(profile[r // 2:r + r // 2 + 1], 10))
            left, right = float(profile[:r - skip].max()), float(profile[r + 1 + skip:].max())
            background = 0.5 * (left + right)
            if background <= core or abs(left - right) > 0.25 * (background - core):
                continue
            half = 0.5 * (background + core)
            i = int(np.argmax(profile[:r - skip]))  # the crest on each side; the crossing lies between it and the middle
            j = r + 1 + skip + int(np.argmax(profile[r + 1 + skip:]))
            inside = np.flatnonzero(profile[i:j + 1] < half) + i
            if inside.size == 0:
                continue
            a, b = inside[0], inside[-1]
            start = (a - 1) + (half - profile[a - 1]) / (profile[a] - profile[a - 1])
            stop = b + (half - profile[b]) / (profile[b + 1] - profile[b])
            widths.append(stop - start)
        if widths:
            out[k] = float(np.mean(widths))
    return out
