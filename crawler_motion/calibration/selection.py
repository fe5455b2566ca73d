"""Selection of the identification poses: the subset of candidates whose stacked Jacobian has
the smallest condition number (greedy D-optimal start, then exchanges), and the random
baseline it is compared with."""

from __future__ import annotations

import numpy as np

from crawler_motion.calibration.jacobian import column_scale, condition_number

#: Exchange passes over the selection after the greedy start.
EXCHANGE_PASSES = 2


def _rows(jac: np.ndarray, picks: list[int]) -> np.ndarray:
    return jac.reshape(-1, 3, jac.shape[1])[picks].reshape(-1, jac.shape[1])


def select(jac: np.ndarray, count: int) -> list[int]:
    """Indices of ``count`` poses out of the candidates' stacked Jacobian ``jac`` (3 rows per
    candidate): greedily add the pose that most raises log det(JᵀJ + εI) of the normalised
    Jacobian, then swap selected for unselected poses while the condition number falls."""
    n = jac.shape[0] // 3
    if not 0 < count <= n:
        raise ValueError(f"cannot select {count} of {n} candidate poses")
    scaled = (jac / column_scale(jac)).reshape(n, 3, -1)
    eps = 1e-9 * np.eye(jac.shape[1])
    info = eps.copy()
    picks: list[int] = []
    for _ in range(count):
        rest = [i for i in range(n) if i not in picks]
        gains = [np.linalg.slogdet(info + scaled[i].T @ scaled[i])[1] for i in rest]
        best = rest[int(np.argmax(gains))]
        picks.append(best)
        info = info + scaled[best].T @ scaled[best]
    current = condition_number(_rows(jac, picks))
    for _ in range(EXCHANGE_PASSES):
        improved = False
        for slot in range(count):
            for cand in range(n):
                if cand in picks:
                    continue
                trial = picks.copy()
                trial[slot] = cand
                value = condition_number(_rows(jac, trial))
                if value < current:
                    picks, current, improved = trial, value, True
        if not improved:
            break
    return picks


def random_conditions(jac: np.ndarray, count: int, draws: int, rng: np.random.Generator
                      ) -> np.ndarray:
    """Condition numbers of ``draws`` random ``count``-pose subsets of the candidates."""
    n = jac.shape[0] // 3
    return np.array([condition_number(_rows(jac, list(rng.choice(n, count, replace=False))))
                     for _ in range(draws)])
