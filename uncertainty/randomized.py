"""Probabilistic certificates from random samples: how often can a design fail?

Randomized robustness analysis (Tempo, Calafiore & Dabbene, *Randomized Algorithms
for Analysis and Control of Uncertain Systems*, Springer 2005/2013, ch. 8-9) replaces
"every member of the box" by "all but a small fraction of the population": draw ``N``
members independently from the parameters' distributions (never the members a design
was tuned on), check the specification on each, and count the ``k`` failures. The
unknown failure probability ``p`` then satisfies, with confidence ``1 - beta``,

    p <= epsilon,   where   sum_{i=0}^{k} C(N, i) epsilon^i (1 - epsilon)^(N - i) = beta,

the one-sided Clopper-Pearson bound. The binomial tail is a regularised incomplete beta
function, so ``epsilon = B^{-1}(1 - beta; k + 1, N - k)`` (the ``1 - beta`` quantile of
a Beta(k + 1, N - k) law; ``epsilon = 1`` when ``k = N``). Without failures this is the
closed form ``epsilon = 1 - beta^(1/N)``, and inverting it gives the sample complexity of
the worst-case (Chernoff-free) bound,

    N >= ln(1/beta) / ln(1/(1 - epsilon))

(Tempo, Bai & Dabbene 1997): 1,375 failure-free samples prove ``p <= 0.01`` with
confidence ``1 - 10^-6``. The samples must be independent draws (Monte Carlo): a Latin
hypercube sample is not, and the bound does not apply to it.
"""

from __future__ import annotations

import dataclasses
import math

from scipy import stats

from robust.checks import Spec, check_int, check_scalar
from robust.errors import ParameterError
from robust.jsonio import to_jsonable

__all__ = [
    "DEFAULT_CONFIDENCE",
    "CoverageBound",
    "failure_bound",
    "samples_needed",
    "hoeffding_halfwidth",
    "coverage_consistent",
]

#: Default confidence ``1 - beta`` of the certificates.
DEFAULT_CONFIDENCE = 0.999

_OPEN_UNIT = Spec(low=0.0, high=1.0, low_open=True, high_open=True)


def failure_bound(samples: int, failures: int, confidence: float = DEFAULT_CONFIDENCE) -> float:
    """Upper bound ``epsilon`` on the failure probability, with confidence ``confidence``.

    The one-sided Clopper-Pearson bound (module notes): the ``epsilon`` at which ``k`` or
    fewer failures in ``N`` independent trials have probability ``beta = 1 - confidence``.

    Parameters
    ----------
    samples : int
        Independent samples ``N`` (>= 1).
    failures : int
        Failures ``k`` among them (0 <= k <= N).
    confidence : float
        ``1 - beta``, in (0, 1).

    Returns
    -------
    float
        ``epsilon`` in (0, 1]; 1 when every sample failed.

    Raises
    ------
    robust.errors.ParameterError
        If a count is out of range or ``confidence`` is not in (0, 1).
    """
    n = check_int("samples", samples, low=1, owner="failure_bound")
    k = check_int("failures", failures, low=0, owner="failure_bound")
    if k > n:
        raise ParameterError(f"failure_bound: failures must be at most samples ({n}); got {k}")
    conf = check_scalar("failure_bound: confidence", confidence, _OPEN_UNIT)
    if k == n:
        return 1.0
    if k == 0:
        return float(-math.expm1(math.log1p(-conf) / n))
    return float(stats.beta.ppf(conf, k + 1, n - k))


def samples_needed(epsilon: float, confidence: float = DEFAULT_CONFIDENCE) -> int:
    """Failure-free samples that prove ``P(failure) <= epsilon`` with confidence ``confidence``.

    ``N = ceil(ln(1/beta) / ln(1/(1 - epsilon)))`` with ``beta = 1 - confidence``
    (module notes).

    Parameters
    ----------
    epsilon : float
        Failure probability to prove, in (0, 1).
    confidence : float
        ``1 - beta``, in (0, 1).

    Returns
    -------
    int

    Raises
    ------
    robust.errors.ParameterError
        If either argument is not in (0, 1).
    """
    eps = check_scalar("samples_needed: epsilon", epsilon, _OPEN_UNIT)
    conf = check_scalar("samples_needed: confidence", confidence, _OPEN_UNIT)
    return int(math.ceil(math.log1p(-conf) / math.log1p(-eps) - 1e-12))


@dataclasses.dataclass(frozen=True)
class CoverageBound:
    """The fraction of a population on which a property held, with its certificate.

    Parameters
    ----------
    samples : int
        Independent samples checked.
    failures : int
        Samples on which the property failed.
    confidence : float
        Confidence ``1 - beta`` of ``epsilon``.
    seed : int
        Seed of the samples.
    method : str
        How the samples were drawn (``"mc"``: independent draws from the distributions).

    Attributes
    ----------
    fraction : float
        ``1 - failures / samples``, the observed coverage.
    epsilon : float
        :func:`failure_bound`: ``P(failure) <= epsilon`` with confidence ``confidence``.
    lower : float
        ``1 - epsilon``, the certified coverage.
    """

    samples: int
    failures: int
    confidence: float = DEFAULT_CONFIDENCE
    seed: int = 0
    method: str = "mc"

    def __post_init__(self):
        # validates the counts and the confidence
        failure_bound(self.samples, self.failures, self.confidence)
        if self.method != "mc":
            raise ParameterError(
                "CoverageBound.method: the certificate needs independent draws ('mc'); "
                f"got {self.method!r}"
            )

    @property
    def fraction(self) -> float:
        return 1.0 - self.failures / self.samples

    @property
    def epsilon(self) -> float:
        return failure_bound(self.samples, self.failures, self.confidence)

    @property
    def lower(self) -> float:
        return 1.0 - self.epsilon

    def describe(self) -> str:
        """One line: observed coverage, failures and the certificate."""
        return (
            f"coverage {self.fraction:.2%} ({self.failures} failures in {self.samples} "
            f"independent members, seed {self.seed}); P(failure) <= {self.epsilon:.3g} "
            f"with confidence {self.confidence:g}"
        )

    def to_json(self) -> dict:
        """The fields and the derived ``fraction``, ``epsilon``, ``lower``."""
        out = to_jsonable(self)
        out.update(fraction=self.fraction, epsilon=self.epsilon, lower=self.lower)
        return out


def hoeffding_halfwidth(samples: int, confidence: float = DEFAULT_CONFIDENCE) -> float:
    """Two-sided half-width of an observed fraction: ``sqrt(ln(2/beta) / (2 N))``.

    Hoeffding's inequality: the fraction of ``N`` *independent* Bernoulli trials lies within
    this of its mean with probability at least ``1 - beta``. It needs independent (Monte
    Carlo) draws. A Latin hypercube's fraction has at most ``N / (N - 1)`` times their
    variance (Owen 1997), but a variance bound is no tail bound: Hoeffding's does not hold
    for its dependent members, and no half-width is given for it.

    Parameters
    ----------
    samples : int
        ``N`` (>= 1).
    confidence : float
        ``1 - beta``, in (0, 1).

    Returns
    -------
    float
    """
    n = check_int("samples", samples, low=1, owner="hoeffding_halfwidth")
    conf = check_scalar("hoeffding_halfwidth: confidence", confidence, _OPEN_UNIT)
    return math.sqrt(math.log(2.0 / (1.0 - conf)) / (2.0 * n))


def coverage_consistent(
    design: float,
    design_samples: int,
    limit: float,
    confidence: float = DEFAULT_CONFIDENCE,
) -> bool:
    """Whether a design's coverage is consistent with a limit coverage that bounds it.

    The design's coverage is observed on ``design_samples`` independent (Monte Carlo)
    members: its one-sided Clopper-Pearson lower bound at ``confidence`` (:func:`failure_bound`)
    must not exceed ``limit``. The limit's coverage, a fraction of a Latin hypercube's
    members, is taken as it is: it carries no tail bound (:func:`hoeffding_halfwidth`), so
    no sampling error of its own is added (a design that covers more than its limit only
    within the limit's unquantified sampling error is reported inconsistent).

    Parameters
    ----------
    design : float
        The design's observed coverage, in [0, 1].
    design_samples : int
        Its members (>= 1).
    limit : float
        The limit's observed coverage.
    confidence : float
        Confidence of the design's bound, in (0, 1).

    Returns
    -------
    bool
    """
    n = check_int("design_samples", design_samples, low=1, owner="coverage_consistent")
    frac = check_scalar("coverage_consistent: design", design, Spec(low=0.0, high=1.0))
    failures = int(round((1.0 - frac) * n))
    lower = 1.0 - failure_bound(n, failures, confidence)
    return lower <= float(limit)
