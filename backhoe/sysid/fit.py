"""Structured transfer-function fits to a measured frequency response.

Forms (the paper's fixed structures, and general rational models):

* ``"valve"``, Eqn 3: ``K p1 wn^2 / (s (s + p1) (s^2 + 2 zeta wn s + wn^2))``;
  returns :class:`backhoe.model.components.ValveCylinderParams`;
* ``"structure"``, Eqn 4: ``K s^2 prod_i (2 z_i w_i s + w_i^2) / (s^2 + 2 z_i w_i s + w_i^2)``
  with the double zero at ``s = 0`` fixed and ``f1 <= f2`` enforced; returns
  :class:`backhoe.model.components.StructureParams`;
* ``"human"``, Eqn 5: ``K (s + z)^2 / (s^2 (s + p)^2)`` with the double pole at
  ``s = 0`` fixed; returns :class:`backhoe.model.human.LiteralHumanParams`;
* ``"M/N"`` (e.g. ``"2/4"``): a rational model with numerator order ``M`` and
  denominator order ``N`` (``M <= N``, monic denominator); returns
  :class:`RationalParams` and a :class:`control.TransferFunction`.

Each fit runs in two steps:

1. a linear initial estimate: the known factor ``s^k`` is divided out and a
   rational model of the remaining orders is fitted by Levy's linearised
   least squares, refined by Sanathanan-Koerner iterations

       E. C. Levy, "Complex-curve fitting", IRE Trans. Automatic Control
       AC-4(1), 1959, pp. 37-44;
       C. K. Sanathanan and J. Koerner, "Transfer function synthesis as a ratio
       of two complex polynomials", IEEE Trans. Automatic Control 8(1), 1963,
       pp. 56-58;

   then the structured parameters are read from its poles, zeros and gain;
2. nonlinear least squares (:func:`scipy.optimize.least_squares`, trust-region
   reflective with bounds) on the complex logarithm of model over measurement,
   whose real part is the log-magnitude error (nepers) and imaginary part the
   phase error (rad, wrapped to (-pi, pi]). Gains and frequencies are fitted in
   logarithms (so they stay positive), damping ratios within [0.005, 0.995].

Frequencies whose coherence is not significantly above zero (5 % family-wise over
the band, Bonferroni, from the null distribution ``P(gamma_hat^2 > x) = (1 - x)^(n_d - 1)``)
are dropped: there H1 is noise and its log-magnitude is biased upward. The rest are weighted by
``sqrt(gamma^2 / (1 - gamma^2))`` (the inverse of the standard deviation of
``log H1`` up to a constant, Bendat & Piersol, Ch. 9), with ``gamma^2`` the
estimate corrected for its ``1/n_d`` bias and capped at 0.999, and by
``sqrt(delta f / f)`` so that each decade counts alike on the linear Welch grid.
"""

from __future__ import annotations

import dataclasses
import itertools
import math

import control as ct
import numpy as np
import scipy.optimize

from backhoe.sysid.forms import (
    FORM_SPECS,
    FORMS,
    ZETA_BOUNDS,
    RationalParams,
    _Form,
    _tf_of,
    form_system,
    parse_form,
)
from robust.analysis.stability import unstable_mask
from robust.checks import POSITIVE, Spec, check_array, check_int, check_scalar
from robust.errors import DataError, InfeasibleError, ParameterError, SolverError
from robust.sysid.linear import levy_sk
from robust.sysid.spectral import FrequencyResponseEstimate, check_band

__all__ = [
    "FORMS",
    "BandError",
    "FitResult",
    "RationalParams",
    "coherence_threshold",
    "fit_frequency_response",
    "form_system",
    "levy_sk",
    "parse_form",
]

TWO_PI = 2.0 * math.pi
_COH_CAP = 0.999


# --------------------------------------------------------------------------------------
# Results
# --------------------------------------------------------------------------------------
@dataclasses.dataclass(frozen=True)
class BandError:
    """Fit error over one sub-band.

    Attributes
    ----------
    band_hz : (float, float)
        Sub-band edges in Hz.
    n_points : int
        Frequencies used.
    rms_db, rms_deg : float
        Unweighted RMS magnitude error (dB) and phase error (degrees), model vs measured.
    mean_coherence : float
        Mean magnitude-squared coherence over the sub-band.
    """

    band_hz: tuple[float, float]
    n_points: int
    rms_db: float
    rms_deg: float
    mean_coherence: float


@dataclasses.dataclass(frozen=True)
class FitResult:
    """A fitted model and how well it fits.

    Attributes
    ----------
    form : str
        ``"valve"``, ``"structure"``, ``"human"`` or ``"M/N"``.
    params : ValveCylinderParams, StructureParams, LiteralHumanParams or RationalParams
        The fitted parameters, as the plant's own parameter objects.
    system : control.TransferFunction
        The fitted model (rad/s).
    band_hz : (float, float)
        Fit band in Hz.
    fit_error_db, fit_error_deg : float
        Weighted RMS magnitude (dB) and phase (degrees) errors over the band,
        with the fit's own weights (normalised to sum 1).
    band_errors : tuple of BandError
        Unweighted errors per sub-band.
    std_errors : dict
        Linearised standard errors of the parameters (same units), from the
        Jacobian at the solution and the residual variance; indicative only.
    correlation : numpy.ndarray, shape (n_params, n_params)
        Linearised correlation matrix of the parameters.
    initial : dict
        Parameters of the linear (Levy/Sanathanan-Koerner) estimate.
    notes : tuple of str
        Identifiability and quality remarks (parameters at bounds, strong
        correlations, poorly determined parameters, unstable poles).
    n_points : int
        Frequencies used in the fit.
    cost : float
        Final least-squares cost ``0.5 * sum r^2``.
    coherence_threshold : float
        Frequencies with coherence below this were left out (``min_coherence``
        or the significance threshold, whichever is higher).
    """

    form: str
    params: object
    system: ct.TransferFunction
    band_hz: tuple[float, float]
    fit_error_db: float
    fit_error_deg: float
    band_errors: tuple[BandError, ...]
    std_errors: dict
    correlation: np.ndarray
    initial: dict
    notes: tuple[str, ...]
    n_points: int
    cost: float
    coherence_threshold: float = 0.0

    @property
    def param_names(self) -> tuple[str, ...]:
        """Parameter names, in the parameter object's order."""
        return tuple(self.params_dict())

    def params_dict(self) -> dict[str, float]:
        """Parameter name -> value."""
        if isinstance(self.params, RationalParams):
            return self.params.as_dict()
        return {k: float(v) for k, v in dataclasses.asdict(self.params).items()}

    def frequency_response(self, f_hz) -> np.ndarray:
        """Model response at frequencies ``f_hz`` (Hz), complex, shape like ``f_hz``.

        Parameters
        ----------
        f_hz : array_like
            Finite frequencies, Hz, any shape.

        Raises
        ------
        ParameterError
            If a frequency is not numeric or not finite.
        """
        f = check_array("FitResult.frequency_response: f_hz", f_hz)
        return np.asarray(self.system(1j * TWO_PI * f), dtype=complex).reshape(f.shape)

    def to_dict(self) -> dict:
        """JSON-ready summary."""
        return {
            "form": self.form,
            "params_class": type(self.params).__name__,
            "params": self.params_dict(),
            "std_errors": dict(self.std_errors),
            "initial": dict(self.initial),
            "fit_error_db": self.fit_error_db,
            "fit_error_deg": self.fit_error_deg,
            "band": list(self.band_hz),
            "band_errors": [dataclasses.asdict(b) for b in self.band_errors],
            "n_points": self.n_points,
            "coherence_threshold": self.coherence_threshold,
            "notes": list(self.notes),
        }


# --------------------------------------------------------------------------------------
# The fit
# --------------------------------------------------------------------------------------
_UNIT_OPEN = Spec(low=0.0, high=1.0, low_open=True, high_open=True)


def coherence_threshold(n_effective: float, significance: float) -> float:
    """Coherence that a zero-coherence estimate exceeds with probability ``significance``.

    For an estimate from ``n_effective`` averages of a true coherence of zero:
    ``1 - significance^(1 / (n_d - 1))``.

    Under zero true coherence ``P(gamma_hat^2 > x) = (1 - x)^(n_d - 1)`` (Bendat & Piersol, Ch. 9).

    Parameters
    ----------
    n_effective : float
        Effective number of independent averages ``n_d`` of the estimate.
    significance : float
        Probability, in (0, 1), that a zero-coherence estimate exceeds the threshold.

    Raises
    ------
    ParameterError
        If ``n_effective`` is not finite and positive or ``significance`` not in (0, 1).
    """
    n_effective = check_scalar("coherence_threshold: n_effective", n_effective, POSITIVE)
    significance = check_scalar("coherence_threshold: significance", significance, _UNIT_OPEN)
    nd = max(float(n_effective), 1.0 + 1e-9)
    return 1.0 - significance ** (1.0 / (nd - 1.0))


def _debiased_coherence(coh: np.ndarray, n_effective: float) -> np.ndarray:
    """``(n_d gamma_hat^2 - 1) / (n_d - 1)``, clipped to [0, 1].

    Removes the ``1/n_d`` floor of the estimate.
    """
    nd = max(float(n_effective), 1.0 + 1e-9)
    return np.clip((nd * coh - 1.0) / (nd - 1.0), 0.0, 1.0)


def _weights(
    f: np.ndarray, coh: np.ndarray, n_effective: float, weighting: str, log_spacing: bool
) -> np.ndarray:
    if weighting == "coherence":
        g2 = np.clip(_debiased_coherence(coh, n_effective), 0.0, _COH_CAP)
        w = np.sqrt(g2 / (1.0 - g2))
    elif weighting == "none":
        w = np.ones_like(f)
    else:
        raise ParameterError(f"weighting must be 'coherence' or 'none'; got {weighting!r}")
    if log_spacing:
        df = np.gradient(f) if f.size > 1 else np.ones_like(f)
        w = w * np.sqrt(np.abs(df) / f)
    return w


def _log_ratio(model: np.ndarray, meas: np.ndarray) -> np.ndarray:
    return np.log(model / meas)


def _band_errors(f, model, meas, coh, lo, hi, n_sub) -> tuple[BandError, ...]:
    edges = np.geomspace(lo, hi, n_sub + 1)
    lr = _log_ratio(model, meas)
    out = []
    for a, b in itertools.pairwise(edges):
        m = (f >= a) & (f <= b)
        if not np.any(m):
            continue
        db = 20.0 / math.log(10.0) * lr.real[m]
        deg = np.degrees(lr.imag[m])
        out.append(
            BandError(
                band_hz=(float(a), float(b)),
                n_points=int(np.count_nonzero(m)),
                rms_db=float(np.sqrt(np.mean(db**2))),
                rms_deg=float(np.sqrt(np.mean(deg**2))),
                mean_coherence=float(np.mean(coh[m])),
            )
        )
    return tuple(out)


def _usable(estimate, band_hz, min_coherence, significance):
    mask = estimate.band_mask(band_hz)
    mask &= np.isfinite(estimate.h1) & (np.abs(estimate.h1) > 0)
    threshold = min_coherence
    if significance is not None:
        # family-wise over the band (Bonferroni): with no true coherence anywhere in the band,
        # no frequency passes with probability 1 - significance
        per_bin = significance / max(int(np.count_nonzero(mask)), 1)
        threshold = max(threshold, coherence_threshold(estimate.n_effective, per_bin))
    mask &= estimate.coherence >= threshold
    return mask, threshold


def fit_frequency_response(
    estimate: FrequencyResponseEstimate,
    form: str,
    band_hz: tuple[float, float],
    *,
    weighting: str = "coherence",
    log_spacing: bool = True,
    min_coherence: float = 0.0,
    significance: float | None = 0.05,
    n_subbands: int = 3,
    initial=None,
    starts: int = 8,
) -> FitResult:
    """Fit ``form`` to an H1 estimate over ``band_hz``.

    Parameters
    ----------
    estimate : FrequencyResponseEstimate
        Measured H1 and coherence (see :func:`estimate_frequency_response`).
    form : str
        ``"valve"`` (Eqn 3), ``"structure"`` (Eqn 4), ``"human"`` (Eqn 5), or
        ``"M/N"`` for a rational model of numerator order ``M`` and denominator
        order ``N``.
    band_hz : (float, float)
        Fit band ``(lo, hi)`` in Hz; must lie inside the data.
    weighting : str
        ``"coherence"`` (default; see the module notes) or ``"none"``.
    log_spacing : bool
        Weight each frequency by ``sqrt(delta f / f)`` so decades count alike (default True).
    min_coherence : float
        Drop frequencies whose coherence is below this, in [0, 1).
    significance : float or None
        Also drop frequencies whose coherence is not significantly above zero, at
        this family-wise level over the band's ``n`` frequencies (per-frequency level
        ``significance / n``, Bonferroni; default 0.05; see :func:`coherence_threshold`).
        At such frequencies H1 is noise and its log-magnitude is biased upward, and
        among hundreds of noise-only frequencies a per-frequency 5 % test would let
        dozens through. ``None`` keeps them all.
    n_subbands : int
        Number of log-equal sub-bands in the error report.
    initial : parameter object, optional
        Start the nonlinear refinement here instead of the linear estimate
        (fixed forms only; the linear estimate is still run and reported).
    starts : int
        Number of starting points for the nonlinear refinement (the linear
        estimate and perturbations of its frequencies), best kept.

    Returns
    -------
    FitResult

    Raises
    ------
    DataError
        If the band lies outside the data or holds too few frequencies.
    InfeasibleError
        If fewer usable (coherent) frequencies remain than the fit needs.
    SolverError
        If the nonlinear least squares fails or returns non-finite parameters.
    ParameterError
        For a bad form, weighting, threshold, ``n_subbands`` or ``starts`` (integers >= 1)
        or an ``estimate`` that is not a :class:`FrequencyResponseEstimate`.
    """
    if not isinstance(estimate, FrequencyResponseEstimate):
        raise ParameterError(
            "fit_frequency_response: estimate must be a FrequencyResponseEstimate; "
            f"got {type(estimate).__name__}"
        )
    check_int("fit_frequency_response: n_subbands", n_subbands, low=1)
    check_int("fit_frequency_response: starts", starts, low=1)
    parsed = parse_form(form)
    lo, hi = check_band(band_hz)
    if not (isinstance(min_coherence, (int, float)) and 0.0 <= min_coherence < 1.0):
        raise ParameterError(f"min_coherence must be in [0, 1); got {min_coherence!r}")
    if significance is not None and not (
        isinstance(significance, (int, float)) and 0.0 < significance < 1.0
    ):
        raise ParameterError(f"significance must be in (0, 1) or None; got {significance!r}")
    mask, threshold = _usable(estimate, (lo, hi), min_coherence, significance)
    f = estimate.f_hz[mask]
    hm = estimate.h1[mask]
    coh = estimate.coherence[mask]
    w = _weights(f, coh, estimate.n_effective, weighting, log_spacing)
    n_par = (
        (parsed[0] + parsed[1] + 1) if isinstance(parsed, tuple) else len(FORM_SPECS[parsed].names)
    )
    if f.size < max(n_par, 3) or np.count_nonzero(w > 0) < n_par:
        raise InfeasibleError(
            f"only {f.size} usable frequencies in band [{lo:g}, {hi:g}] Hz "
            f"(coherence >= {threshold:.3g}); the {form!r} form has {n_par} parameters. "
            "Widen the band, add records or lower min_coherence"
        )
    omega = TWO_PI * f
    s = 1j * omega
    if isinstance(parsed, tuple):
        result = _fit_rational(form, parsed, f, s, hm, coh, w, lo, hi, n_subbands)
    else:
        result = _fit_fixed(
            FORM_SPECS[parsed], f, s, hm, coh, w, lo, hi, n_subbands, initial, starts
        )
    return dataclasses.replace(result, coherence_threshold=float(threshold))


def _residual_fn(spec: _Form, s, hm, w):
    def fun(theta):
        model = spec.response(spec.from_theta(theta), s)
        lr = _log_ratio(model, hm)
        return np.concatenate([w * lr.real, w * lr.imag])

    return fun


def _starts(spec: _Form, p0: np.ndarray, n: int) -> list[np.ndarray]:
    """The linear estimate first, then perturbations of its frequencies.

    For the structure the ordering ``f1 <= f2`` makes the assignment of the two
    damping ratios to the lower and upper mode part of the answer, and the
    merged-mode point ``f1 = f2`` is a stationary point of the separation; so the
    starts spread the modes apart and try both damping assignments.
    """
    out = [p0]
    if spec.name == "structure":
        k, z1, z2, f1, f2 = p0
        fc = math.sqrt(f1 * f2)
        for ratio in (1.05, 1.2, 1.5, 1.02):
            r = math.sqrt(ratio)
            out.append(np.array([k, z2, z1, fc / r, fc * r]))
            out.append(np.array([k, z1, z2, fc / r, fc * r]))
        out.insert(1, np.array([k, z2, z1, f1, f2]))
    else:
        for factor in (0.7, 1.4, 2.0, 0.5):
            q = p0.copy()
            for i, name in enumerate(spec.names):
                if name.endswith("_hz") or name in ("p1", "z1"):
                    q[i] = q[i] * factor
            out.append(q)
    return out[: max(1, n)]


def _clip_theta(theta, lo, hi):
    span = np.where(np.isfinite(hi - lo), (hi - lo) * 1e-6, 0.0)
    return np.clip(theta, lo + span, hi - span)


def _fit_fixed(spec, f, s, hm, coh, w, lo, hi, n_sub, initial, starts) -> FitResult:
    m, n = spec.init_orders
    target = hm / s**spec.s_power
    inverted = False
    try:
        num, den = levy_sk(2 * np.pi * f, target, m, n, weights=w / np.abs(target))
        inverted = _linear_gain_sign(spec, num, den) < 0
        p_lin = spec.from_rational(num, den)
        if not np.all(np.isfinite(p_lin)) or np.any(
            p_lin[[i for i, nm in enumerate(spec.names) if not nm.startswith("zeta")]] <= 0
        ):
            raise SolverError("linear estimate gave non-physical parameters")
    except (SolverError, np.linalg.LinAlgError, DataError, ParameterError):
        # (a zero of H1 gives an infinite weight, which levy_sk refuses)
        p_lin = _generic_start(spec, f, hm)
    p_lin = _physical(spec, p_lin)
    if spec.name == "structure" and p_lin[3] > p_lin[4]:
        p_lin = p_lin[[0, 2, 1, 4, 3]]
    p0 = p_lin
    if initial is not None:
        if not isinstance(initial, spec.params_class):
            raise ParameterError(
                f"initial must be a {spec.params_class.__name__} for form {spec.name!r}; "
                f"got {type(initial).__name__}"
            )
        p0 = np.array([getattr(initial, nm) for nm in spec.names], dtype=float)
    omega_lo, omega_hi = TWO_PI * lo, TWO_PI * hi
    tlo, thi = spec.theta_bounds(omega_lo, omega_hi)
    fun = _residual_fn(spec, s, hm, w)
    best = None
    for q in _starts(spec, p0, starts):
        theta0 = _clip_theta(spec.to_theta(_physical(spec, q)), tlo, thi)
        try:
            res = scipy.optimize.least_squares(
                fun, theta0, bounds=(tlo, thi), method="trf", x_scale="jac", max_nfev=2000
            )
        except (ValueError, np.linalg.LinAlgError) as exc:
            raise SolverError(
                f"nonlinear least squares failed for form {spec.name!r}: {exc}"
            ) from None
        if not np.all(np.isfinite(res.x)) or not math.isfinite(res.cost):
            continue
        if best is None or res.cost < best.cost:
            best = res
    if best is None:
        raise SolverError(
            f"nonlinear least squares for form {spec.name!r} did not return a usable solution"
        )
    p = spec.from_theta(best.x)
    try:
        params = spec.params_class(**dict(zip(spec.names, (float(v) for v in p))))
    except ParameterError as exc:
        raise SolverError(f"fitted {spec.name!r} parameters are not physical: {exc}") from None
    model = spec.response(p, s)
    cov_nat = _covariance(spec, best, p)
    notes = _notes(spec, best, tlo, thi, p, cov_nat, lo, hi)
    if best.status == 0:
        notes += ("nonlinear least squares stopped at its evaluation limit before converging",)
    offset = _mean_phase_offset_deg(model, hm, w)
    if inverted or abs(offset) > 90.0:
        why = (
            "the linear estimate's gain is negative"
            if inverted
            else f"the measured phase sits {offset:+.0f} deg from the fitted form's on average"
        )
        notes += (
            (
                f"{why}: the data look inverted (check the sign of a sensor or channel; "
                "the form's gain is positive) or the form does not match them"
            ),
        )
    return _result(
        spec.name,
        params,
        _tf_of(spec.name, p),
        f,
        model,
        hm,
        coh,
        w,
        lo,
        hi,
        n_sub,
        spec.names,
        p,
        cov_nat,
        dict(zip(spec.names, map(float, p_lin))),
        notes,
        best.cost,
    )


def _linear_gain_sign(spec, num, den) -> float:
    """Sign of the form's gain in the linear estimate.

    ``R(0)``, or ``R``'s leading coefficient for the human.
    """
    if spec.name == "human":
        return float(np.sign(num[0]))
    return float(np.sign(num[-1] * den[-1]))


def _mean_phase_offset_deg(model, meas, w) -> float:
    """Weighted circular mean of the phase of measured over model, degrees."""
    z = np.sum(w**2 * np.exp(1j * np.angle(meas / model)))
    return float(np.degrees(np.angle(z)))


def _physical(spec, p):
    p = np.array(p, dtype=float)
    for i, nm in enumerate(spec.names):
        if nm.startswith("zeta"):
            p[i] = min(max(p[i], ZETA_BOUNDS[0]), ZETA_BOUNDS[1])
        else:
            p[i] = abs(p[i]) if p[i] != 0 else 1.0
    return p


def _generic_start(spec, f, hm) -> np.ndarray:
    """A start when the linear estimate fails: frequencies at the band's geometric centre."""
    fc = float(np.exp(np.mean(np.log(f))))
    guess = {
        "k_vc": 1.0,
        "p1": TWO_PI * fc * 4,
        "wn_hz": fc,
        "zeta": 0.3,
        "k_s": 1.0,
        "zeta1": 0.2,
        "zeta2": 0.2,
        "f1_hz": fc,
        "f2_hz": fc * 1.1,
        "k_h": 1.0,
        "z1": TWO_PI * fc * 2,
    }
    if spec.name == "human":
        guess["p1"] = TWO_PI * fc / 4
    p = np.array([guess[nm] for nm in spec.names])
    # match the median gain
    ratio = np.median(np.abs(hm) / np.abs(spec.response(p, 1j * TWO_PI * f)))
    p[0] *= ratio
    return p


def _jacobian_natural(spec, theta) -> np.ndarray:
    """d natural / d theta, by central differences (the maps are smooth and cheap)."""
    n = theta.size
    jac = np.empty((n, n))
    for j in range(n):
        h = 1e-6 * max(1.0, abs(theta[j]))
        tp, tm = theta.copy(), theta.copy()
        tp[j] += h
        tm[j] -= h
        jac[:, j] = (spec.from_theta(tp) - spec.from_theta(tm)) / (2 * h)
    return jac


def _covariance(spec, res, p):
    m = res.fun.size
    n = res.x.size
    dof = max(m - n, 1)
    s2 = 2.0 * res.cost / dof
    jtj = res.jac.T @ res.jac
    cov_t = s2 * np.linalg.pinv(jtj)
    t = _jacobian_natural(spec, res.x)
    return t @ cov_t @ t.T


def _bound_note(spec, i: int, edge: float, side: str) -> str:
    label = spec.theta_labels[i]
    if label == "ln(f2_hz/f1_hz)":
        what = "f2_hz/f1_hz" if side == "upper" else "f2_hz/f1_hz (the modes merged into one)"
        return (
            f"{what} is at its {side} bound {math.exp(edge):g}: "
            "the two modes are not separated by these data"
        )
    if label.startswith("ln "):
        return (
            f"{label[3:]} is at its {side} bound {math.exp(edge):.4g}: not identified by these data"
        )
    return f"{label} is at its {side} bound {edge:g}: not identified by these data"


def _notes(spec, res, tlo, thi, p, cov, lo, hi) -> tuple[str, ...]:
    notes = []
    names = list(spec.names)
    for i, x in enumerate(res.x):
        for edge, side in ((tlo[i], "lower"), (thi[i], "upper")):
            if math.isfinite(edge) and abs(x - edge) <= 1e-6 * max(1.0, abs(edge)):
                notes.append(_bound_note(spec, i, edge, side))
    sd = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    for i, nm in enumerate(names):
        if p[i] != 0 and sd[i] / abs(p[i]) > 0.25:
            notes.append(
                f"{nm} is poorly determined: linearised relative standard error "
                f"{sd[i] / abs(p[i]):.0%}"
            )
    with np.errstate(invalid="ignore", divide="ignore"):
        corr = cov / np.outer(sd, sd)
    for i in range(len(names)):
        for j in range(i + 1, len(names)):
            if np.isfinite(corr[i, j]) and abs(corr[i, j]) > 0.95:
                notes.append(
                    f"{names[i]} and {names[j]} are strongly correlated (r = {corr[i, j]:+.3f})"
                )
    if spec.name == "structure":
        z1, z2, f1, f2 = p[1], p[2], p[3], p[4]
        sep = (f2 - f1) / f1
        half_bw = max(z1, z2)
        if sep < 2.0 * half_bw:
            notes.append(
                f"the two modes are {sep:.1%} apart, less than their half-power bandwidth "
                f"(about {2 * half_bw:.0%}): they overlap in the response, and only the fixed "
                "form separates "
                "them; f1/f2 and zeta1/zeta2 trade off against each other (see correlation and "
                "std_errors) and become unidentifiable as coherence falls"
            )
    for nm, val in zip(names, p):
        if nm.endswith("_hz") and not (lo <= val <= hi):
            notes.append(
                f"{nm} = {val:.4g} Hz lies outside the fit band [{lo:g}, {hi:g}] Hz: extrapolated"
            )
        if nm in ("p1", "z1") and not (lo <= val / TWO_PI <= hi):
            notes.append(
                f"{nm} = {val:.4g} rad/s ({val / TWO_PI:.3g} Hz) lies outside the fit band "
                f"[{lo:g}, {hi:g}] Hz: extrapolated"
            )
    return tuple(notes)


def _result(
    form, params, system, f, model, hm, coh, w, lo, hi, n_sub, names, p, cov, initial, notes, cost
):
    lr = _log_ratio(model, hm)
    wn = w**2 / np.sum(w**2)
    err_db = float(np.sqrt(np.sum(wn * (20.0 / math.log(10.0) * lr.real) ** 2)))
    err_deg = float(np.sqrt(np.sum(wn * np.degrees(lr.imag) ** 2)))
    sd = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    with np.errstate(invalid="ignore", divide="ignore"):
        corr = cov / np.outer(sd, sd)
    corr.setflags(write=False)
    return FitResult(
        form=form,
        params=params,
        system=system,
        band_hz=(float(lo), float(hi)),
        fit_error_db=err_db,
        fit_error_deg=err_deg,
        band_errors=_band_errors(f, model, hm, coh, lo, hi, n_sub),
        std_errors={nm: float(v) for nm, v in zip(names, sd)},
        correlation=corr,
        initial=initial,
        notes=notes,
        n_points=int(f.size),
        cost=float(cost),
    )


def _fit_rational(form, orders, f, s, hm, coh, w, lo, hi, n_sub) -> FitResult:
    m, n = orders
    omega = TWO_PI * f
    num0, den0 = levy_sk(omega, hm, m, n, weights=w / np.abs(hm))
    w0 = float(np.exp(np.mean(np.log(omega))))
    # refine in the scaled variable s/w0: coefficients of comparable size
    sc = s / w0
    bn = num0[::-1] * w0 ** np.arange(m + 1) / w0**n
    an = den0[::-1] * w0 ** np.arange(n + 1) / w0**n  # an[n] == 1

    def unpack(x):
        return x[: m + 1], np.concatenate([x[m + 1 :], [1.0]])

    def fun(x):
        b, a = unpack(x)
        model = np.polyval(b[::-1], sc) / np.polyval(a[::-1], sc)
        with np.errstate(divide="ignore", invalid="ignore"):
            lr = np.log(model / hm)
        lr = np.where(np.isfinite(lr), lr, 1e3)
        return np.concatenate([w * lr.real, w * lr.imag])

    x0 = np.concatenate([bn, an[:n]])
    try:
        res = scipy.optimize.least_squares(fun, x0, method="trf", x_scale="jac", max_nfev=4000)
    except (ValueError, np.linalg.LinAlgError) as exc:
        raise SolverError(
            f"nonlinear least squares failed for rational form {form!r}: {exc}"
        ) from None
    if not np.all(np.isfinite(res.x)):
        raise SolverError(
            f"nonlinear least squares for rational form {form!r} returned non-finite coefficients"
        )
    b, a = unpack(res.x)
    num = b[::-1] / w0 ** np.arange(m, -1, -1) * w0**n
    den = a[::-1] / w0 ** np.arange(n, -1, -1) * w0**n
    params = RationalParams(num=tuple(num), den=tuple(den))
    system = params.transfer_function()
    model = np.polyval(num, s) / np.polyval(den, s)
    notes = []
    poles = np.roots(den)
    if np.any(unstable_mask(poles)):
        notes.append(
            f"fitted model has {int(np.sum(unstable_mask(poles)))} pole(s) in the right half-plane"
        )
    names = list(params.as_dict())
    # covariance in scaled coefficients -> natural coefficients (diagonal scaling)
    dof = max(res.fun.size - res.x.size, 1)
    cov_x = 2.0 * res.cost / dof * np.linalg.pinv(res.jac.T @ res.jac)
    scale = np.concatenate([w0**n / w0 ** np.arange(m + 1), w0**n / w0 ** np.arange(n)])
    cov_nat_x = cov_x * np.outer(scale, scale)
    # order as in as_dict: b_M..b_0, a_N..a_0 (a_N fixed at 1: zero variance)
    idx_b = list(range(m, -1, -1))
    cov = np.zeros((len(names), len(names)))
    order = idx_b + [None] + list(range(m + n, m, -1))
    for i, oi in enumerate(order):
        for j, oj in enumerate(order):
            if oi is not None and oj is not None:
                cov[i, j] = cov_nat_x[oi, oj]
    initial = RationalParams(num=tuple(num0), den=tuple(den0)).as_dict()
    p_nat = np.array(list(params.as_dict().values()))
    return _result(
        form,
        params,
        system,
        f,
        model,
        hm,
        coh,
        w,
        lo,
        hi,
        n_sub,
        names,
        p_nat,
        cov,
        initial,
        tuple(notes),
        res.cost,
    )
