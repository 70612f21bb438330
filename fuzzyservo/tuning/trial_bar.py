"""The study's progress bar on stderr: finished trials of the total, the best value so far.

A tqdm bar counting trials from where a resumed study stands (or a silent stand-in with
``progress`` off). It stays in the tuning package: :mod:`fuzzyservo.progress` is a layer
above it (pyproject.toml's import-linter contract), so tuning may not use it."""

from __future__ import annotations

from fuzzyservo.tuning.study_trials import best_feasible_value, count_complete


def refresh(bar, study) -> None:
    """Bring the bar up to the study's finished trials (read from the storage)."""
    n = count_complete(study)
    if n > bar.n:
        bar.update(n - bar.n)
    postfix(bar, study)


def postfix(bar, study) -> None:
    """Show the study's best value so far beside the bar (single-objective studies)."""
    if isinstance(bar, _NoBar):
        return  # nothing shows it: no need to look (the parent's time is the workers')
    best = _best_value(study)
    if best is not None:
        bar.set_postfix_str(f"best {best:.4g}")


def _best_value(study) -> float | None:
    """The best feasible value so far (Optuna's ``best_value`` among the trials that meet
    the constraints, without the copy of the best trial it makes)."""
    if len(study.directions) != 1:
        return None
    return best_feasible_value(study)


class _NoBar:
    n = 0

    def update(self, k: int = 1) -> None:
        self.n += k

    def set_postfix_str(self, text: str) -> None:
        pass

    def close(self) -> None:
        pass


def trial_bar(total: int, initial: int, name: str, enabled: bool):
    """A tqdm bar of ``total`` trials starting at ``initial``; a silent one if not ``enabled``."""
    import sys

    if not enabled:
        bar = _NoBar()
        bar.n = initial
        return bar
    from tqdm import tqdm

    return tqdm(
        total=total,
        initial=initial,
        desc=name,
        unit="trial",
        file=sys.stderr,
        dynamic_ncols=True,
        mininterval=0.5,
    )
