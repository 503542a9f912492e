"""The ``cosserat-solid`` medium: finite-rotation micropolar solids on SE(3) (paper §VI.A)."""
