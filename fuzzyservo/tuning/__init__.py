"""Tuning studies: a study spec, the trial objective, and the Optuna runner (the only optuna user)."""
