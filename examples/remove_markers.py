"""Marker removal (TELEA and biharmonic), scored against the true markerless image.

The same code as the README's example; tests/test_readme.py keeps the two equal."""

import tacswitch as ts
from tacswitch import metrics
from tacswitch.sim import render_sample

s = render_sample("gelsight_mini", seed=0)          # a contact, with markers and without
clean = ts.remove_markers(s.image_markers)          # adaptive mask per marker, TELEA r=12
smooth = ts.remove_markers(s.image_markers, method="biharmonic")
print(f"TELEA {metrics.masked_mae(clean, s.image, s.marker_mask):.2f} grey levels, "
      f"biharmonic {metrics.masked_mae(smooth, s.image, s.marker_mask):.2f}")
