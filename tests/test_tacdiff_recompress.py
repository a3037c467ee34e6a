"""Re-compressing the fine-tune's transplants like the source (tacswitch.tacdiff.recompress)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tacswitch.sim.capture import jpeg_roundtrip
from tacswitch.tacdiff.data import marker_offset_pairs
from tacswitch.tacdiff.recompress import jpeg_quality, recompressor


@settings(max_examples=8, deadline=None)
@given(quality=st.integers(30, 93))
def test_the_quality_of_a_jpeg_source_is_recognised(mini, quality: int) -> None:
    src = jpeg_roundtrip(mini.imgs[2], quality)
    found = jpeg_quality(src)
    # The quality itself or a neighbour with the same tables: re-compressing there reproduces
    # the source's quantisation.
    assert found is not None and abs(found - quality) <= 2
    assert np.abs(jpeg_roundtrip(src, found).astype(int) - src).mean() < 0.1


def test_lossless_and_video_sources_are_not_taken_for_jpeg(mini, marker_frames) -> None:
    assert jpeg_quality(mini.imgs[2]) is None  # real frame, never JPEG-compressed here
    assert jpeg_quality(marker_frames[0]) is None
    pytest.importorskip("av")
    from tacswitch.sim.capture import h264_roundtrip

    assert jpeg_quality(h264_roundtrip([mini.imgs[2]], 26)[0]) is None


def test_specs_and_their_errors(mini) -> None:
    src = jpeg_roundtrip(mini.imgs[2], 70)
    fn, text = recompressor("auto", [src])
    assert text == "jpeg:70" and fn is not None
    np.testing.assert_array_equal(fn(mini.imgs[3]), jpeg_roundtrip(mini.imgs[3], 70))
    assert recompressor("auto", [mini.imgs[2]])[0] is None
    assert recompressor("None", [src]) == (None, "none")
    assert recompressor("jpeg:40", [])[1] == "jpeg:40"
    assert recompressor("h264:23", [])[1] == "h264:23"
    for bad in ("jpeg", "jpeg:0", "jpeg:x", "h264:60", "png:3", ""):
        with pytest.raises(ValueError, match=r"^recompress: expected"):
            recompressor(bad, [src])


def test_transplanted_inputs_are_recompressed_and_targets_are_not(marker_frames) -> None:
    src = [jpeg_roundtrip(f, 60) for f in marker_frames]
    plain = marker_offset_pairs(src, offset=(16, 16))
    redo = marker_offset_pairs(src, offset=(16, 16), recompress=lambda f: jpeg_roundtrip(f, 60))
    np.testing.assert_array_equal(redo["target"], plain["target"])
    np.testing.assert_array_equal(redo["mask"], plain["mask"])
    np.testing.assert_array_equal(redo["cond"], np.stack([jpeg_roundtrip(c, 60)
                                                          for c in plain["cond"]]))
    assert not np.array_equal(redo["cond"], plain["cond"])
