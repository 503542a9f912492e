"""The ``kirchhoff-love`` medium: thin plates and shells adapted to their Gauss map (paper §VII.B)."""
