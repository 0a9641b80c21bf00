"""Units of one design calibrated together: the fleet database, the design's prior."""
