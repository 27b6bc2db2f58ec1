"""The marker dictionaries: every code against OpenCV's predefined dictionaries (the oracle the
data was carried over from), and reading bits in any turn with the dictionary's correction."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from camkit.errors import ParameterError
from camkit.target import DICTIONARY_NAMES, get_dictionary


@pytest.mark.parametrize("name", DICTIONARY_NAMES)
def test_every_code_is_opencvs(name):
    ref = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, name))
    d = get_dictionary(name)
    assert len(d) == ref.bytesList.shape[0] and d.marker_size == ref.markerSize
    assert d.max_correction_bits == ref.maxCorrectionBits
    bits = np.array([cv2.aruco.Dictionary.getBitsFromByteList(ref.bytesList[i:i + 1], ref.markerSize)
                     for i in range(len(d))])
    np.testing.assert_array_equal(d.codes, bits)
    # A marker image from OpenCV, cell by cell: 1 = white, a black border.
    img = cv2.aruco.generateImageMarker(ref, len(d) - 1, (d.marker_size + 2) * 4)
    np.testing.assert_array_equal(img[2::4, 2::4] > 127, d.cells(len(d) - 1) == 1)


@pytest.mark.parametrize("name", ["DICT_4X4_50", "DICT_5X5_100", "DICT_6X6_250", "DICT_APRILTAG_36h11"])
def test_identify_in_every_turn_with_correctable_errors(name):
    d = get_dictionary(name)
    rng = np.random.default_rng(5)
    for code in rng.choice(len(d), 10, replace=False):
        for turns in range(4):
            seen = np.rot90(d.codes[code], turns).copy()
            flip = rng.choice(seen.size, d.max_correction_bits, replace=False)
            seen.flat[flip] ^= 1
            assert d.identify(seen) == (code, turns, d.max_correction_bits)
    # Uniform bits are no code of these dictionaries (their minimum distance forbids it).
    assert d.identify(np.zeros((d.marker_size, d.marker_size), np.uint8)) is None


def test_bad_input_is_named():
    with pytest.raises(ParameterError, match=r"dictionary: expected one of .*DICT_5X5_100.*got .DICT_5X5_101."):
        get_dictionary("DICT_5X5_101")
    with pytest.raises(ParameterError, match=r"bits: expected shape \(5, 5\)"):
        get_dictionary("DICT_5X5_100").identify(np.zeros((4, 4)))


def test_identify_many_names_a_bad_shape():
    with pytest.raises(ParameterError, match=r"bits: expected shape \(K, 6, 6\), got \(6, 6\)"):
        get_dictionary("DICT_6X6_250").identify_many(np.zeros((6, 6)))


@pytest.mark.parametrize("name", DICTIONARY_NAMES)
def test_packed_hamming_matching_is_the_product_forms(name):
    """identify_many matches the bits packed into one word (kernel nearest_codes); the product
    form it replaced (kept for codes of over 64 bits) is the oracle: the same ids, turns and
    errors, ties included, on codes turned and flipped at random and on random bits."""
    d = get_dictionary(name)
    n = d.marker_size
    rng = np.random.default_rng(11)
    K = 400
    bits = np.stack([np.rot90(d.codes[i], t) for i, t in zip(rng.integers(0, len(d), K), rng.integers(0, 4, K),
                                                              strict=True)])
    bits ^= (rng.random(bits.shape) < rng.random(K)[:, None, None] * 0.1).astype(np.uint8)
    bits[:50] = rng.integers(0, 2, (50, n, n))
    packed, product = d.identify_many(bits), d._identify_wide(bits)
    for a, b in zip(packed, product, strict=True):
        np.testing.assert_array_equal(a, b)
    assert (packed[0] >= 0).any() and (packed[0] < 0).any()  # both outcomes drawn
