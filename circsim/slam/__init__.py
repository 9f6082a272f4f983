"""The bench SLAM: each robot's pose estimate and log-odds map in its own frame (:mod:`.models`: the
``scan_matching`` and ``odometry_only`` models) and the scan-to-map matcher (:mod:`.scanmatch`, compiled
kernels). Configuration: :class:`circsim.config.types.SlamConfig`.
"""
