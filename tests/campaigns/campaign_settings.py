"""The small reference campaign every campaign test compares with (imported by name: a module name
unique in the test tree, unlike ``conftest``)."""

SUITE = "ncap-v1"
HOURS = 0.04  # 144 s of NCAP tests: 10 scenarios
CHUNK = 3  # -> 4 chunks (3, 3, 3, 1)
CONTROLLER = "acc"
