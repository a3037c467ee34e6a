"""TacDiff marker removal (and the hybrid mode), scored against the true markerless image.

The same code as the README's example; tests/test_readme.py keeps the two equal."""

import tacswitch as ts
from tacswitch import metrics
from tacswitch.sim import render_sample

s = render_sample("gelsight_mini", seed=0)
clean = ts.remove_markers(s.image_markers, method="tacdiff")   # K=1 step, 4 orientations averaged
quick = ts.remove_markers(s.image_markers, method="hybrid", ref=s.reference)  # net near contact
for name, out in [("tacdiff", clean), ("hybrid", quick)]:
    print(name, f"{metrics.masked_mae(out, s.image, s.marker_mask):.2f} grey levels")
