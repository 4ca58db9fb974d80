"""How large a height-map file may be, and the check made before one is read.

Every bound follows from the most grid points a surface may have (`planarize.heightfield.MAX_POINTS`):
a file larger than a surface of that many points could need is refused from its size, before
anything is read (`checked_file`). What the readers then allocate is bounded too: text tables by
their count of numbers (`planarize.io.texttable`), ``.npy`` arrays and ``.gwy`` channels by their
declared shapes.
"""

from __future__ import annotations

import os
import stat

from labrig.validate import InputError

from ..heightfield import MAX_POINTS

#: Characters one number of a text height map takes at most, with its separator: the longest float64
#: (``-1.2345678901234567e-100,``) takes 25; the rest is room for padding and line ends.
TEXT_BYTES_PER_VALUE = 32
#: Bytes of a ``.npy`` header, at most (numpy's own limit is 10,000).
NPY_HEADER_BYTES = 1 << 16
#: Bytes of a ``.gwy`` file besides its largest channel: other channels of the same scan, metadata. The
#: ``gwyfile`` package reads the whole file and holds about five copies of it while decoding (measured
#: 5.6x for one channel), so the cap is what bounds the memory of a ``.gwy`` import (~1.5 GB at the cap).
GWY_OTHER_BYTES = 8 * MAX_POINTS + (1 << 20)
#: Channels an instrument's file (`planarize.io.instrument`) may hold beside the one read: an AFM records a
#: handful at once (height, error, phase, ..., each trace and retrace); AFMReader reads the whole file.
INSTRUMENT_CHANNELS = 16
#: Largest file read, bytes, by format: a matrix has one number per point, an XYZ file three, a ``.npy``
#: array at most 16 bytes per value (a long double), a ``.gwy`` file 8 per value of its height channel, an
#: instrument's file 8 per value of `INSTRUMENT_CHANNELS` channels.
MAX_FILE_BYTES = {
    "matrix": TEXT_BYTES_PER_VALUE * MAX_POINTS,
    "xyz": 3 * TEXT_BYTES_PER_VALUE * MAX_POINTS,
    "npy": NPY_HEADER_BYTES + 16 * MAX_POINTS,
    "gwy": 8 * MAX_POINTS + GWY_OTHER_BYTES,
    **dict.fromkeys(("spm", "ibw", "jpk", "stp", "top", "nid", "park", "mi"),
                    8 * INSTRUMENT_CHANNELS * MAX_POINTS + (1 << 20)),
}


def checked_file(path, format: str) -> int:
    """Size of the height map ``path``, bytes, once it is known to be a regular file within its ``format``'s
    `MAX_FILE_BYTES`; nothing is read.

    Raises
    ------
    FileNotFoundError
        If nothing is at ``path`` (a dangling symbolic link included).
    InputError
        A symbolic link loop (or another path that cannot be opened), a directory or a pipe, a file
        larger than the cap.
    """
    try:
        info = os.stat(path)
    except FileNotFoundError:
        raise FileNotFoundError(f"height map {str(path)!r} does not exist") from None
    except OSError as exc:  # ELOOP: a symbolic link loop; EACCES, ENAMETOOLONG, ...
        raise InputError(f"cannot open the file: {exc.strerror or exc}") from None
    if not stat.S_ISREG(info.st_mode):
        raise InputError("not a regular file (a directory or a pipe?)")
    limit = MAX_FILE_BYTES[format]
    if info.st_size > limit:
        raise InputError(f"the file has {info.st_size:,} bytes, more than the {limit:,} a {format} height map of at "
                         f"most {MAX_POINTS:,} points may have")
    return info.st_size
