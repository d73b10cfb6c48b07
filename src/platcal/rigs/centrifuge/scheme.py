"""The centrifuge's named positions (docs/centrifuge-model.md §7); the scheme type and its checks
are shared (:mod:`platcal.scheme`)."""

TABLE1_POSITIONS = ((45, 0, 167), (350, 0, 325), (209, 0, 182), (134, 0, 141), (106, 0, 338), (142, 0, 269))
"""The paper's optimal 6-position scheme (Table 1), deg."""
