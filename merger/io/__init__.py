"""Map files in and out: ROS map_server maps (:mod:`.mapio`; their files read and checked: :mod:`.mapread`),
ROS 2 bags (:mod:`.bagio`) and the thesis's colour overlay (:mod:`.overlay`). Every problem with a file is
one :class:`~merger.io.mapread.MapFileError` line naming the file; files are written atomically. The
algorithms never import this package; the input limits it enforces are :mod:`merger.limits` (docs/limits.md).
"""
