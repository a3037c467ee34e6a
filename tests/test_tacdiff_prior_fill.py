"""realproxy.prior_fill: the benchmark's "prior" rows use the shipped models' TELEA radius."""

from __future__ import annotations

import numpy as np
import pytest

from tacswitch import realproxy as R
from tacswitch.tacdiff.prior import DEFAULT_PRIOR_RADIUS, from_net, prior_planes


def test_prior_fill_uses_the_shipped_prior_radius(marker_frames):
    img = marker_frames[0]
    mask = R.default_mask(img)
    kind = "telea+biharmonic-grown"
    got = R.prior_fill(kind)(img, None)
    np.testing.assert_array_equal(got[~mask], img[~mask])
    want = from_net(prior_planes(img, mask, kind, DEFAULT_PRIOR_RADIUS)[0])
    np.testing.assert_array_equal(got[mask], want[mask])
    r3 = R.prior_fill(kind, 3)(img, None)
    assert not np.array_equal(r3[mask], got[mask])  # the radius matters on these holes
    assert any(k.startswith(f"prior {kind} r={DEFAULT_PRIOR_RADIUS} ")
               for k in R.methods((12,), models=False, priors=(kind,)))
    with pytest.raises(ValueError, match="radius"):
        R.prior_fill(kind, 0)
