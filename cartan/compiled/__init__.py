"""The compiled layer's machinery: generated modules (:mod:`.codegen`), the kernel
declarations they bind (:mod:`.kernels`), the operator sets schemes hand to the integrators'
loops (:mod:`.operators`) and compile progress on stderr (:mod:`.progress`)."""
