"""Evaluations above the twin and the diagnosis: the blind gap benchmark."""
