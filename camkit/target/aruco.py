"""Square fiducial marker dictionaries (ArUco, AprilTag): the codes, and reading a marker's bits.

The codes are data: OpenCV's predefined dictionaries (``cv2.aruco.getPredefinedDictionary``;
the AprilTag families are AprilRobotics/apriltag's), carried over as
``camkit/target/data/aruco_dictionaries.json`` by ``scripts/make_aruco_dictionaries.py`` and
checked code by code against OpenCV in tests/target/test_aruco.py. A marker of an ``n x n``
dictionary is ``(n + 2) x (n + 2)`` cells: a black border one cell wide around the ``n x n``
bits, 1 = white, read row by row from the marker's top-left corner.
"""

from __future__ import annotations

import functools
import json
from dataclasses import dataclass
from importlib import resources

import numpy as np

from camkit._kernels import markers as markers_kernels
from camkit.errors import ParameterError

__all__ = ["DICTIONARY_NAMES", "ArucoDictionary", "get_dictionary"]


@functools.cache
def _data() -> dict:
    return json.loads(resources.files("camkit.target").joinpath("data/aruco_dictionaries.json").read_text())


#: The predefined dictionary names, as OpenCV spells them (``"DICT_5X5_100"``).
DICTIONARY_NAMES: tuple[str, ...] = tuple(sorted(_data()["dictionaries"]))


@dataclass(frozen=True, slots=True, eq=False)
class ArucoDictionary:
    """A marker dictionary.

    Attributes
    ----------
    name : str
    marker_size : int
        Bits per side, n.
    codes : ndarray, (N, n, n) uint8
        Code ``i``'s bits, 1 = white, row by row from the marker's top-left corner.
    max_correction_bits : int
        Bit errors corrected when reading (OpenCV's value for the dictionary).
    """

    name: str
    marker_size: int
    codes: np.ndarray
    max_correction_bits: int

    def __len__(self) -> int:
        return len(self.codes)

    def cells(self, marker_id: int) -> np.ndarray:
        """The marker's ``(n + 2) x (n + 2)`` cells, 1 = white (the border is black)."""
        n = self.marker_size
        out = np.zeros((n + 2, n + 2), dtype=np.uint8)
        out[1:-1, 1:-1] = self.codes[marker_id]
        return out

    def identify(self, bits: np.ndarray) -> tuple[int, int, int] | None:
        """``(id, turns, errors)`` of the code nearest to the observed ``n x n`` bits in any of
        the four quarter turns, or None where more than ``max_correction_bits`` bits differ.
        ``turns``: the observed bits are the code turned ``turns`` times by ``np.rot90`` (a
        quarter turn counter-clockwise as the array is printed), so the code's corner ``j``
        (0 top-left, 1 top-right, 2 bottom-right, 3 bottom-left) is the observed bits' corner
        ``(j - turns) % 4``."""
        b = np.asarray(bits, dtype=np.uint8)
        n = self.marker_size
        if b.shape != (n, n):
            raise ParameterError(f"bits: expected shape ({n}, {n}), got {b.shape}")
        ids, turns, errors = self.identify_many(b[None])
        return None if ids[0] < 0 else (int(ids[0]), int(turns[0]), int(errors[0]))

    def identify_many(self, bits: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`identify` for ``(K, n, n)`` observed bits at once: ``(ids, turns, errors)``,
        each (K,), id -1 where no code is within ``max_correction_bits``."""
        b = np.asarray(bits)
        n = self.marker_size
        if b.ndim != 3 or b.shape[1:] != (n, n):
            raise ParameterError(f"bits: expected shape (K, {n}, {n}), got {b.shape}")
        K = b.shape[0]
        if n * n > 64:  # (no predefined dictionary: at most 7 x 7 bits)
            return self._identify_wide(b)
        ids = np.empty(K, dtype=np.int64)
        turns = np.empty(K, dtype=np.int64)
        errors = np.empty(K, dtype=np.int64)
        # Hamming distances to every code in each quarter turn, the bits packed into one word
        # (kernel :func:`camkit._kernels.markers.nearest_codes`): the observed bits turned back
        # ``t`` times differ from a code where they differ from the code turned ``t`` times.
        markers_kernels.nearest_codes(np.ascontiguousarray((b != 0).reshape(K, n * n), dtype=np.uint8),
                                      _turned_codes(self.codes.tobytes(), len(self.codes), n), ids, turns, errors)
        ids[errors > self.max_correction_bits] = -1
        return ids, turns, errors

    def _identify_wide(self, bits: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`identify_many` for codes of more than 64 bits, by products: bits that agree
        are 1*1 or 0*0."""
        b = np.asarray(bits != 0, dtype=np.float64)
        n, K = self.marker_size, bits.shape[0]
        turned = np.stack([np.rot90(b, -k, axes=(1, 2)).reshape(K, -1) for k in range(4)], axis=1)  # undo k turns
        codes = self.codes.reshape(len(self.codes), -1).astype(np.float64)
        flat = (n * n - (turned @ codes.T + (1.0 - turned) @ (1.0 - codes).T)).reshape(K, -1)  # (K, 4 N)
        best = np.argmin(flat, axis=1)
        errors = flat[np.arange(K), best].astype(np.int64)
        turns, ids = np.divmod(best, len(self.codes))
        ids = np.where(errors <= self.max_correction_bits, ids, -1)
        return ids.astype(np.int64), turns.astype(np.int64), errors


@functools.lru_cache(maxsize=16)
def _turned_codes(codes: bytes, N: int, n: int) -> np.ndarray:
    """(4, N) uint64: each of the ``N`` codes (``n x n`` uint8 bits as bytes) turned ``t``
    quarter turns by ``np.rot90``, its cells row by row as bits 0, 1, ... of one word."""
    c = np.frombuffer(codes, dtype=np.uint8).reshape(N, n, n)
    shifts = np.arange(n * n, dtype=np.uint64)
    return np.stack([(np.rot90(c, t, axes=(1, 2)).reshape(N, -1).astype(np.uint64) << shifts).sum(axis=1,
                                                                                                 dtype=np.uint64)
                     for t in range(4)])


@functools.cache
def get_dictionary(name: str) -> ArucoDictionary:
    """The predefined dictionary ``name`` (OpenCV's spelling, e.g. ``"DICT_5X5_100"``,
    ``"DICT_APRILTAG_36h11"``)."""
    data = _data()
    entry = data["dictionaries"].get(name) if isinstance(name, str) else None
    if entry is None:
        raise ParameterError(f"dictionary: expected one of {', '.join(DICTIONARY_NAMES)}, got {name!r}")
    fam = data["families"][entry["family"]]
    n = fam["marker_size"]
    codes = np.array([[int(c) for c in format(int(h, 16), f"0{n * n}b")] for h in fam["codes"][:entry["size"]]],
                     dtype=np.uint8).reshape(-1, n, n)
    codes.setflags(write=False)
    return ArucoDictionary(name, n, codes, entry["max_correction_bits"])
