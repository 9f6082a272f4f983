"""The simulated world: the room and its objects in pymunk (:mod:`.world`), the robots' paths on the
circle (:mod:`.motion`) and the 2D laser (:mod:`.laser`); a map world's walls (:mod:`.mapgeometry`) and
generated floor plans (:mod:`.floorplan`). The only package of ours that imports pymunk.
"""
