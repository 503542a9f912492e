"""The ``cosserat-surface`` medium: geometrically exact Cosserat plates and shells on SE(3) (paper §VI.B)."""
