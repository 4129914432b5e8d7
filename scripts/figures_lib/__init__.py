"""The sections and helpers of scripts/figures.py (see its docstring)."""
