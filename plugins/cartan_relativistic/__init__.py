"""The ``relativistic-rod`` medium: rods and strings in Minkowski space on the Poincaré group (paper §VIII.C)."""
