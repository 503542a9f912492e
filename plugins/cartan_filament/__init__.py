"""The ``filament`` plugin: the Kirchhoff filament, an inextensible and unshearable rod on
SE(3) whose constrained strains are held by the statics' Lagrange multipliers (paper §III.E,
§IV.E, §VII.A)."""
