"""Sim-to-real gap diagnosis: where the analytical model's error lies, which unmodelled effect
causes it, and how far it shrinks once that effect is modelled (``docs/diagnosis.md``)."""
