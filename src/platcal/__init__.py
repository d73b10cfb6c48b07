"""platcal: identification of inertial-platform error coefficients from test-rig data."""

__version__ = "0.1.0"
