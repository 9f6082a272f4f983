"""What a run leaves behind: the rerun recording (:mod:`.rerun`, :mod:`.entities`, :mod:`.viewer`; the
only package of ours that imports rerun), the robots' maps as ROS files (:mod:`.savemaps`) and the
JSON/CSV number format (:mod:`.jsonout`). Each is an observer of the run or a writer; the simulation
loop knows none of them.
"""
