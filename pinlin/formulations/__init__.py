"""The linear formulations of chapter 9.1: independent coordinates (9.1.1) so far."""

from .independent import linearize_independent

FORMULATIONS = ("independent", "penalty", "canonical")

__all__ = ["FORMULATIONS", "linearize_independent"]
