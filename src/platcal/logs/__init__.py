"""Real test logs, for every rig, on top of the one reader (:mod:`platcal.records`, which applies
the column/unit mapping of :mod:`platcal.mapping`): what a log holds (:mod:`.summary`), the
static dwells of a continuous log (:mod:`.dwells`), increments (:mod:`.increments`) and the
calibration file an identification writes and ``platcal compensate`` applies
(:mod:`.calibration`, :mod:`.compensate`). Nothing here names a rig: each rig passes its
record's columns and units."""
