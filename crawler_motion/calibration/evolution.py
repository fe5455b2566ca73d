"""Differential evolution (Storn–Price rand/1/bin) on a box, vectorised over the population."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

#: Mutation weight F and crossover rate CR (Storn–Price's usual values).
MUTATION = 0.5
CROSSOVER = 0.9


@dataclass(frozen=True)
class Evolution:
    """Best point, its cost, the cost after every generation and the evaluations used."""

    best: np.ndarray
    cost: float
    history: np.ndarray
    evaluations: int


def evolve(cost: Callable[[np.ndarray], np.ndarray], low: np.ndarray, high: np.ndarray,
           population: int, generations: int, rng: np.random.Generator,
           seed_point: np.ndarray | None = None) -> Evolution:
    """Minimise ``cost`` (rows of points ``(P, D)`` -> costs ``(P,)``) in the box [low, high].

    Mutation ``V = X_r1 + F (X_r2 - X_r3)`` (r1, r2, r3 distinct and not the target), binomial
    crossover with CR and at least one gene from V, greedy selection. A trial outside the box
    is reflected back into it. ``seed_point`` (if given) is member 0 of the first population,
    so the result is never worse than it.
    """
    dims = len(low)
    if population < 4:
        raise ValueError(f"differential evolution needs a population of >= 4, got {population}")
    pop = low + rng.random((population, dims)) * (high - low)
    if seed_point is not None:
        pop[0] = seed_point
    fit = cost(pop)
    history = [float(fit.min())]
    idx = np.arange(population)
    for _ in range(generations):
        r = np.array([rng.choice(np.delete(idx, i), 3, replace=False) for i in idx])
        mutant = pop[r[:, 0]] + MUTATION * (pop[r[:, 1]] - pop[r[:, 2]])
        cross = rng.random((population, dims)) < CROSSOVER
        cross[idx, rng.integers(0, dims, population)] = True
        trial = np.where(cross, mutant, pop)
        trial = np.where(trial < low, 2 * low - trial, trial)
        trial = np.where(trial > high, 2 * high - trial, trial)
        trial = np.clip(trial, low, high)  # a reflection past the far side (tiny boxes)
        trial_fit = cost(trial)
        better = trial_fit <= fit
        pop[better], fit[better] = trial[better], trial_fit[better]
        history.append(float(fit.min()))
    best = int(np.argmin(fit))
    return Evolution(pop[best].copy(), float(fit[best]), np.array(history),
                     population * (generations + 1))
