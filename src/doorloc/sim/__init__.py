"""Simulation: a renderer of doors and calibration boards with exactly known truth.

- :mod:`doorloc.sim.raster` — exact box-filtered rasterisation of textured planar surfaces through the
  OpenCV camera model (distortion included, no resampling);
- :mod:`doorloc.sim.door` — :func:`~doorloc.sim.door.render_door`: the door solid (with chamfered or
  rounded arris) placed by :func:`doorloc.pose.door_to_cell`, background and distractors, true corner pixel;
- :mod:`doorloc.sim.boards` — :func:`~doorloc.sim.boards.render_board` for checkerboards and ChArUco boards;
- :mod:`doorloc.sim.effects` — :class:`~doorloc.sim.effects.Effects` (every effect off by default) and the
  optics/sensor pipeline;
- :mod:`doorloc.sim.dataset` — pose grids, ``truth.csv`` writing/reading, ``doorloc render``'s work;
- :mod:`doorloc.sim.edgecheck` — the independent area-method check of rendered edge positions.
- :mod:`doorloc.sim.hostile` — image files made to cost a decoder far more than their size (the
  service's hostile-client tests and benchmark).
"""
