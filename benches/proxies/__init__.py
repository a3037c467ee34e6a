"""Evaluation proxies of the benches and the tests, kept out of the installed package (no
command and no public function of ``tacswitch`` needs them; issue 33).

- :mod:`motion_proxy`: real-texture proxies for marker motion (taxim's real markerless frames
  warped by known fields, or with the simulator's field of their own contact);
- :mod:`slip_proxy`: grasp videos of real texture for markerless slip.

Import them with ``benches/`` on the import path, as the bench scripts have it
(``from proxies import motion_proxy as proxy``); ``tests/conftest.py`` puts it there for the
tests. They import ``tacswitch`` (and taxim's data, ``tacswitch[test]``); ``tacswitch`` never
imports them.
"""
