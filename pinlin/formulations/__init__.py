"""The linear formulations of chapter 9.1: independent coordinates (9.1.1), penalty (9.1.2)
and canonical (9.1.3)."""

from .constrained import (
    BASES,
    PENALTY_DEFAULTS,
    linearize_canonical,
    linearize_penalty,
    linearize_reduced,
)
from .independent import linearize_independent

FORMULATIONS = ("independent", "penalty", "canonical")

__all__ = ["BASES", "FORMULATIONS", "PENALTY_DEFAULTS", "linearize_canonical",
           "linearize_independent", "linearize_penalty", "linearize_reduced"]
