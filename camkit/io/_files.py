"""What every reader checks before it opens a path."""

from __future__ import annotations

import stat
from pathlib import Path

__all__ = ["regular_file_size"]


def regular_file_size(p: Path, error: type[Exception], expected: str, what: str = "file") -> int:
    """The size in bytes of ``p``, after checking that it is a regular file: a named pipe would
    block a read forever and a device (/dev/zero) fill the memory. Raises ``error`` naming
    ``p``: "cannot read the {what} (why)" where it cannot be looked at, "expected {expected},
    got a folder" (or "not a regular file")."""
    try:
        st = p.stat()
    except OSError as exc:
        raise error(f"{p}: cannot read the {what} ({exc.strerror or exc})") from None
    if not stat.S_ISREG(st.st_mode):
        kind = "a folder" if stat.S_ISDIR(st.st_mode) else "not a regular file"
        raise error(f"{p}: expected {expected}, got {kind}")
    return st.st_size
