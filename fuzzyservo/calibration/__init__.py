"""Calibration against measured data: replay, residual analysis, effect candidates."""
