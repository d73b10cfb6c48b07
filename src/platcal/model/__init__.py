"""The physical model shared by the rigs: frames and rotations (:mod:`.frames`), the gyro and
accelerometer error terms (:mod:`.instruments`, one source for every kernel) and the platform's
attitude dynamics and measurement on a base whose specific force is an input (:mod:`.attitude`).
Nothing here names a rig."""
