"""The numeric layer: code generated from the derivation (standalone Python/C/JavaScript and
the compiled simulation kernels), the kernel cache, and the integrators. No SymPy on a cache hit."""
