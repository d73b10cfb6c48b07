"""The physical model shared by the rigs: frames and rotations (:mod:`.frames`), the gyro and
accelerometer error terms (:mod:`.instruments`, one source for every kernel) and the platform's
error model as one object (:mod:`.platform`). Nothing here names a rig."""
