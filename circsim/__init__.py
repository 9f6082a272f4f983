"""circsim — the simulation bench for common-center map merging.

A scenario file (``circsim/scenarios/*.yaml``) describes a room, its objects and three robots on a
circle around the scene's center. The bench builds the world in pymunk, casts a 2D laser, runs a
synthetic SLAM per robot in its own map frame, exchanges maps over a simulated network and measures
the :mod:`merger` library against ground truth. Conventions are in ``DESIGN.md``; the packages
(``config``, ``world``, ``slam``, ``record``, ``experiments``) follow the data flow, docs/design/layout.md.
"""
