"""The one check every input file passes before it is opened: it exists, it is a regular
file (a named pipe could block the command forever, a device such as /dev/urandom never
ends, a folder is not a file) and it is below the size cap of its kind. Errors are one
InputError line naming the file; symlinks are followed (a link to a device is a device).
"""

from __future__ import annotations

import os
import stat

from ..base.errors import InputError

# Size caps, bytes. A CSV log: a 30-minute 5 kHz encoder log is about 250 MB; 4 GiB leaves
# room for 8 h at that rate while refusing a disk image given by mistake.
MAX_CSV_BYTES = 4 << 30


def check_input_file(path, what: str = "file", max_bytes: int | None = None) -> os.stat_result:
    """Refuse path unless it is an existing regular file of at most max_bytes bytes.

    what: what the command expected (for the message, e.g. "calibration JSON"). Returns its
    stat. Errors: InputError(path, ...) for missing, a folder, a named pipe, a device, a
    socket, unreadable or too large."""
    try:
        st = os.stat(path)
    except FileNotFoundError:
        raise InputError(path, f"file not found (a {what} was expected)") from None
    except OSError as e:
        raise InputError(path, f"cannot read: {e.strerror or e}; check the path and its permissions") from None
    m = st.st_mode
    if stat.S_ISDIR(m):
        raise InputError(path, f"is a folder, not a {what}")
    if not stat.S_ISREG(m):
        kind = ("a named pipe (FIFO)" if stat.S_ISFIFO(m) else "a device" if stat.S_ISCHR(m) or stat.S_ISBLK(m)
                else "a socket" if stat.S_ISSOCK(m) else "not a regular file")
        raise InputError(path, f"is {kind}, not a {what}: playscope reads regular files only (save the data to a file)")
    if max_bytes is not None and st.st_size > max_bytes:
        raise InputError(path, f"{st.st_size / 2**20:.0f} MiB, above the {max_bytes / 2**20:.0f} MiB a {what} may have; "
                         "is it the right file?")
    return st
