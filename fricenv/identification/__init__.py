"""Friction identification from a measured record, and the design of the excitation that
reveals the friction best.

- :func:`identify` fits each candidate friction law by output-error least squares on the
  exact simulator (exact Jacobian through every stick/slip switch) and ranks them by BIC;
- :func:`design_excitation` chooses the two-tone forcing that maximises the expected
  Fisher information of a prior plant.

SciPy and threadpoolctl are needed (the ``identify`` extra): ``pip install 'fricenv[identify]'``.
"""

from __future__ import annotations

from .design import DEFAULT_EXCITATION, Design, design_excitation
from .fit import LawFit
from .identify import IdentificationResult, identify
from .model import DEFAULT_LAWS, LAW_UNKNOWNS, simulate_record

__all__ = ["DEFAULT_EXCITATION", "DEFAULT_LAWS", "LAW_UNKNOWNS", "Design",
           "IdentificationResult", "LawFit", "design_excitation", "identify",
           "simulate_record"]
