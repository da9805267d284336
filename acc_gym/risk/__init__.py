"""Accelerated evaluation: rare collisions measured by importance sampling (``acc-gym risk``).

A controller that collides once in 100,000 cut-ins is invisible to a few hundred test
episodes. Crude Monte Carlo needs about ``3/p`` episodes to see the first failure at
probability ``p`` and about ``100/p`` for a +-20 % interval. Importance sampling over the
scenario's parameters (Zhao et al., IEEE T-ITS 2017, for cut-ins; Rubinstein's
cross-entropy method to fit the proposal) draws the dangerous part of the naturalistic
distribution more often and weights each episode by its likelihood ratio, so the
estimate stays unbiased with a known variance.

The method (``x``: the scenario's parameters; ``p``: their naturalistic density, the
product of the laws the scenario generator samples from -- :mod:`acc_gym.scenarios`'
normal, log-normal, Laplace and bivariate normal laws with their truncation; ``f(x)``: 1
if the controller fails in that episode, e.g. collides):

* **target** ``P = E_p[f(x)]``, per encounter of the family (one episode); the failure is
  the run's event: a ``collision``, a ``ttc`` under 1 s, or a ``preventable-collision`` (the
  controller collides and UN R157's careful driver, ``cc-driver``, driving the same scenario,
  does not; :mod:`acc_gym.risk.run`);
* **proposal** ``q = beta p + (1 - beta) g``: a defensive mixture (``beta`` = 0.1) of the
  nominal law and ``g``, the same laws with tilted locations and scales
  (:mod:`acc_gym.risk.proposal`);
* **weights** ``w(x) = p(x) / q(x) <= 1 / beta``, computed from the same law objects;
* **estimator** ``P_hat = (1/n) sum w_i f(x_i)``, unbiased for any ``g`` because ``q > 0``
  wherever ``p > 0``;
* **variance** ``Var(P_hat) = (E_q[w^2 f] - P^2) / n``, estimated by the sample variance of
  ``w_i f_i``; 95 % interval ``P_hat +- 1.96 sd``; relative half-width
  ``rhw = 1.96 sd / P_hat`` (:mod:`acc_gym.risk.estimate`);
* **cross-entropy update**: the optimal proposal ``q* = f p / P`` is approached by fitting
  ``g`` to the elite episodes of a round (those at least as dangerous as the round's
  ``rho`` = 10 % quantile of the episode's smallest time-to-collision, or the failures
  once there are enough), weighted by ``w``: for a normal law ``mu' = sum w x / sum w``,
  ``sigma'^2 = sum w (x - mu')^2 / sum w`` (in ``ln x`` for a log-normal; weighted median
  and mean absolute deviation for a Laplace; weighted mean and covariance for a pair),
  smoothed with the previous values (:mod:`acc_gym.risk.run`);
* **acceleration**: crude Monte Carlo would need ``n_crude = 1.96^2 (1 - P) / (P rhw^2)``
  episodes for the same ``rhw``; the factor is ``n_crude`` / the episodes used, adaptive
  rounds included;
* **no failure**: an exact 95 % upper bound ``P <= -ln(0.05) / (beta N)`` after ``N``
  episodes (each draw fails with probability at least ``beta P``), never a bare 0.

Assumptions: the scenario laws are the truth (the estimate is as good as the
naturalistic model behind them); the controller is deterministic given the scenario (or
its randomness is seeded from the scenario), so ``f`` is a function of ``x`` and the
episode's seed; the parameters not tilted (the duration, constants, the surrounding
drivers' parameters) are drawn from their nominal laws, so their ratio is 1. Per hour of
driving: ``P`` times the family's occurrence rate (:data:`acc_gym.scenarios.singlelane.OCCURRENCE_RATES`).

Example (the README's "Rare events" section has the numbers)::

    from acc_gym.risk import estimate_risk
    r = estimate_risk("acc", "cut-in", target_rhw=0.2, budget=20000, workers=2)
    print(r.estimate.p, r.estimate.ci_low, r.estimate.ci_high, r.estimate.acceleration, r.stop)
"""

from acc_gym.risk.estimate import Estimate, crude_episodes, estimate, upper_bound
from acc_gym.risk.proposal import DEFENSIVE, Proposal, tilted_keys
from acc_gym.risk.run import EVENTS, FAMILIES, RiskResult, estimate_risk, resolve_family

__all__ = ["DEFENSIVE", "EVENTS", "FAMILIES", "Estimate", "Proposal", "RiskResult", "crude_episodes", "estimate",
           "estimate_risk", "resolve_family", "tilted_keys", "upper_bound"]
