"""Linear rational fits to a frequency response: Levy's method and Sanathanan-Koerner iterations.

E. C. Levy, "Complex-curve fitting", IRE Trans. Automatic Control AC-4(1),
1959, pp. 37-44;
C. K. Sanathanan and J. Koerner, "Transfer function synthesis as a ratio of
two complex polynomials", IEEE Trans. Automatic Control 8(1), 1963, pp. 56-58.
"""

from __future__ import annotations

import numpy as np

from robust.checks import NONNEGATIVE, POSITIVE, check_int, check_scalar, check_vector
from robust.errors import DataError, InfeasibleError, ParameterError, SolverError

__all__ = ["levy_sk"]


def levy_sk(
    omega: np.ndarray,
    h: np.ndarray,
    m: int,
    n: int,
    *,
    weights: np.ndarray | None = None,
    iterations: int = 20,
    tol: float = 1e-10,
) -> tuple[np.ndarray, np.ndarray]:
    """Rational fit ``N(s)/D(s)`` of numerator order ``m``, monic denominator order ``n``.

    Minimises ``sum_i |w_i (N(j w_i) - H_i D(j w_i)) / D_prev(j w_i)|^2`` with
    ``D_prev = 1`` on the first pass (Levy 1959) and the previous denominator on
    later passes (Sanathanan & Koerner 1963). The frequency is scaled by the
    geometric mean of ``omega`` for conditioning.

    Parameters
    ----------
    omega : array_like, shape (n_f,)
        Angular frequencies in rad/s, > 0.
    h : array_like of complex, shape (n_f,)
        Frequency response to fit.
    m, n : int
        Numerator and denominator orders.
    weights : array_like, shape (n_f,), optional
        Non-negative weights ``w_i`` (default 1).
    iterations : int
        Maximum number of Sanathanan-Koerner passes after Levy's.
    tol : float
        Stop when the relative change of the denominator coefficients is below this.

    Returns
    -------
    num, den : numpy.ndarray
        Polynomial coefficients in ``s`` (rad/s), highest power first; ``den[0] = 1``.

    Raises
    ------
    DataError
        If ``omega`` is not a 1-D array of finite positive frequencies, or ``h`` is not
        numeric, holds NaN or inf, or differs in length from ``omega`` (named).
    ParameterError
        If ``m``, ``n`` or ``iterations`` is not a non-negative integer (``n >= 1``),
        ``weights`` holds a negative or non-finite weight or has the wrong length, or
        ``tol`` is not finite and >= 0.
    InfeasibleError
        If there are fewer equations than coefficients.
    SolverError
        If the linear problem is rank deficient at every pass.
    """
    omega = check_vector("levy_sk: omega", omega, POSITIVE, error=DataError)
    try:
        h = np.asarray(h, dtype=complex)
    except (TypeError, ValueError):
        raise DataError(f"levy_sk: h must be a numeric array; got {type(h).__name__}") from None
    if h.shape != omega.shape:
        raise DataError(
            f"levy_sk: h must have one value per frequency, shape {omega.shape}; got {h.shape}"
        )
    if not np.all(np.isfinite(h)):
        i = int(np.flatnonzero(~np.isfinite(h))[0])
        raise DataError(f"levy_sk: h[{i}] must be finite; got {h[i]!r}")
    m = check_int("levy_sk: m", m, low=0)
    n = check_int("levy_sk: n", n, low=1)
    iterations = check_int("levy_sk: iterations", iterations, low=0)
    tol = check_scalar("levy_sk: tol", tol, NONNEGATIVE)
    if weights is None:
        w = np.ones_like(omega)
    else:
        w = check_vector("levy_sk: weights", weights, NONNEGATIVE)
        if w.shape != omega.shape:
            raise ParameterError(
                f"levy_sk: weights must have one entry per frequency ({omega.size}); got {w.size}"
            )
    if n + m + 1 > 2 * omega.size:
        raise InfeasibleError(
            f"a {m}/{n} rational model has {m + n + 1} coefficients but only "
            f"{omega.size} frequencies (2 real equations each) are available; "
            "widen the band or lower the orders"
        )
    w0 = float(np.exp(np.mean(np.log(omega))))
    s = 1j * omega / w0
    vm = s[:, None] ** np.arange(m + 1)[None, :]  # b_0 .. b_m
    vn = s[:, None] ** np.arange(n)[None, :]  # a_0 .. a_{n-1}
    sn = s**n
    a = np.zeros(n)
    d_prev = np.ones_like(s)
    b = np.zeros(m + 1)
    for _ in range(iterations + 1):
        scale = w / np.abs(d_prev)
        # N(s) - H (s^n + sum a_k s^k) = 0  ->  [vm, -H vn] [b; a] = H s^n
        lhs = np.hstack([vm, -h[:, None] * vn]) * scale[:, None]
        rhs = h * sn * scale
        lhs_r = np.vstack([lhs.real, lhs.imag])
        rhs_r = np.concatenate([rhs.real, rhs.imag])
        col = np.linalg.norm(lhs_r, axis=0)
        col[col == 0] = 1.0
        sol, *_ = np.linalg.lstsq(lhs_r / col, rhs_r, rcond=None)
        sol = sol / col
        if not np.all(np.isfinite(sol)):
            raise SolverError("Levy/Sanathanan-Koerner linear fit returned non-finite coefficients")
        b_new, a_new = sol[: m + 1], sol[m + 1 :]
        change = np.linalg.norm(a_new - a) / max(np.linalg.norm(a_new), 1e-300)
        a, b = a_new, b_new
        d_prev = sn + vn @ a
        if change < tol:
            break
    # undo the scaling s_scaled = s / w0
    num = b[::-1] / w0 ** np.arange(m, -1, -1)
    den_scaled = np.concatenate([[1.0], a[::-1]])
    den = den_scaled / w0 ** np.arange(n, -1, -1)
    num = num * w0**n
    den = den * w0**n
    return num, den
