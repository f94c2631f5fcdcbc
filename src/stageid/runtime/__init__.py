"""How the library runs, not what it computes: compiled kernels, threads, memory, clusters."""
