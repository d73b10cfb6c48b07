"""Real test logs, for every rig: the column/unit mapping of a vendor's log onto a rig's record
(:mod:`.mapping`), what a log holds (:mod:`.inspect`) and the calibration file an identification
writes and ``platcal compensate`` applies (:mod:`.calibration`). Nothing here names a rig: each
rig passes its record's columns and units."""
