"""One subpackage per test rig; each defines ``RIG`` (see :mod:`platcal.rig`)."""
