"""Print the AVX-512 targets of numpy's runtime dispatch (for NPY_DISABLE_CPU_FEATURES: the
Makefile's ``portable`` run disables them; names differ between numpy versions, and numpy
refuses names it does not dispatch)."""

from numpy._core._multiarray_umath import __cpu_dispatch__

if __name__ == "__main__":
    print(" ".join(f for f in __cpu_dispatch__ if "AVX512" in f or f == "X86_V4"))
