"""The study's Optuna sampler, made from its ``sampler`` name (tpe, nsga2, cmaes, qmc, gp,
random) and seed; :func:`~fuzzyservo.tuning.integrity.per_trial_seeded` then seeds it
per trial."""

from __future__ import annotations

from fuzzyservo.errors import require
from fuzzyservo.tuning.spec import Study
from fuzzyservo.tuning.warmstart import stored_violations


def make_sampler(spec: Study, seed: int | None):
    import optuna

    # optuna >= 5 reads the constraints stored by Trial.set_constraint; older ones need constraints_func
    legacy = {}
    if spec.constraints and not hasattr(optuna.trial.Trial, "set_constraint"):
        legacy = {"constraints_func": stored_violations}
    if spec.sampler == "tpe":
        return optuna.samplers.TPESampler(seed=seed, multivariate=True, **legacy)
    if spec.sampler == "nsga2":
        return optuna.samplers.NSGAIISampler(seed=seed, **legacy)
    if spec.sampler == "cmaes":
        return optuna.samplers.CmaEsSampler(seed=seed, warn_independent_sampling=False)
    if spec.sampler == "qmc":  # scrambled Sobol points: space-filling, learns nothing
        return optuna.samplers.QMCSampler(seed=seed, scramble=True, warn_independent_sampling=False)
    if spec.sampler == "gp":  # Gaussian-process Bayesian optimisation (needs PyTorch)
        require("torch", "gp", "the gp sampler (Optuna's GPSampler runs on PyTorch)")
        return optuna.samplers.GPSampler(seed=seed, **legacy)
    return optuna.samplers.RandomSampler(seed=seed)
