"""Independent references for checking fricenv's results.

:mod:`fricenv.testing.scipy_reference` solves the model with SciPy's ``solve_ivp`` and
event location, written from the model page (docs/model.md) alone, not from the kernels,
so that agreement with them means something. The tests and the benchmarks use it; it
needs SciPy, which fricenv does not install. Nothing is imported here, so that importing
the package costs nothing and needs no SciPy.
"""
