"""The study layer: Monte Carlo runner, tidy results, statistics, tables, figures, report.

Nothing here names a rig: it depends on the :class:`platcal.rig.Rig` interface and on the tidy
tables only.
"""
