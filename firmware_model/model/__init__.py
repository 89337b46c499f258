"""model: the bit-exact integer model (numba kernels and its runner), the float references, the per-sample trace
and the synthetic input streams. Imports runtime and spec."""
