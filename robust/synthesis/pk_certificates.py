"""The certificates of the P-K iteration's final controller, each checked independently.

:class:`MemberCertificates` holds, per member, the bounded-real and H2 certificates, the
pole-region certificate of :func:`robust.synthesis.region.certify_region` and their
checks; ``_final_certificates`` rebuilds every inequality in numpy, computes each
member's norms and pole-region violation directly, and refuses a controller that fails
any check, before :func:`robust.synthesis.pk.pksyn_multi` returns. Apart from the
iteration, as the verification of its answer.
"""

from __future__ import annotations

import dataclasses
import math
import time

import control
import numpy as np
import scipy.linalg as sla

from robust.analysis.norms import h2_norm, hinf_norm
from robust.errors import InfeasibleError, SolverError, VerificationError
from robust.synthesis.pk_members import (
    _Affine,
    _bmi,
    _brl_parts,
    _h2_output,
    _h2_parts,
    _max_eig,
    from_scaled,
)
from robust.synthesis.region import RegionCertificate, certify_region, sym

__all__ = ["MemberCertificates"]


# ---------------------------------------------------------------- certificates
@dataclasses.dataclass(frozen=True)
class MemberCertificates:
    """One member's certificates and their independent checks (original coordinates).

    Parameters
    ----------
    region : RegionCertificate or None
        Decay-and-cone certificate of the region plant's closed loop ([CG96]); ``None``
        until :func:`certify_regions` runs when ``pksyn_multi`` deferred it.
    P : numpy.ndarray
        Bounded-real certificate of the decay-shifted H-infinity closed loop at level
        ``gamma_bound`` (plant states, then controller states).
    Q, Z : numpy.ndarray or None
        H2 certificate in the solve's coordinates (recentred, balanced plant states,
        time ``tau = w0 t``; ``None`` without an H2 plant).
    lmi_max_eig : dict
        Largest eigenvalue of each inequality rebuilt in numpy in the solve's
        coordinates (all negative), by name.
    gamma : float
        The member's H-infinity norm, computed independently.
    gamma_bound : float
        The level ``P`` certifies for the decay-shifted channel (so for the channel).
    gamma_shifted : float
        The norm of the decay-shifted closed loop (what ``P`` certifies).
    h2 : float
        The member's H2 norm from the Gramian (0 without an H2 plant).
    h2_bound : float
        The H2 bound the certificate ``Q, Z`` proves, original units
        (``sqrt(w0 trace Z)``).
    region_violation : float
        Largest region violation of the closed-loop poles (negative), rad/s.
    """

    region: RegionCertificate | None
    P: np.ndarray
    Q: np.ndarray | None
    Z: np.ndarray | None
    lmi_max_eig: dict
    gamma: float
    gamma_bound: float
    gamma_shifted: float
    h2: float
    h2_bound: float
    region_violation: float

    def to_json(self) -> dict:
        """The checks (no matrices)."""
        return {
            "region": None if self.region is None else self.region.to_json(),
            "lmi_max_eig": dict(self.lmi_max_eig),
            "gamma": self.gamma,
            "gamma_bound": self.gamma_bound,
            "gamma_shifted": self.gamma_shifted,
            "h2": self.h2,
            "h2_bound": self.h2_bound,
            "region_violation": self.region_violation,
        }


def _region_certificate(m, s, Om_s, nk, w0, region, solvers, solve_times, i, violation=math.nan):
    """The region certificate of one member's closed loop (scaled solve, original ``X``);
    ``violation``: that of its poles, computed by the caller."""
    try:
        t0 = time.perf_counter()
        rs = certify_region(s.region.matrices(Om_s)[0], region.scaled(w0), solvers=solvers)
        solve_times.append(time.perf_counter() - t0)
    except (InfeasibleError, SolverError) as exc:
        raise VerificationError(
            f"pksyn_multi: member {m.label or i}: no region certificate for the final "
            f"controller: {exc}"
        ) from None
    # the region inequalities are homogeneous in X and scale with 1/w0 in time tau: the
    # same X in the original coordinates x = blkdiag(T_state, I) x_s
    Tr = np.linalg.inv(sla.block_diag(s.region_st.T, np.eye(nk)))
    return RegionCertificate(sym(Tr.T @ rs.X @ Tr), rs.lmi_max_eig, violation, rs.method)


def _final_certificates(
    members, scaled, pt, nk, w0, channels, region, solvers, solve_times, with_regions=True
):
    """Certificates of the final point in original coordinates, each checked independently."""
    Om = from_scaled(pt.Om, nk, w0, channels)
    out = []
    for i, (m, s) in enumerate(zip(members, scaled)):
        name = m.label or str(i)
        eigs = {}
        # bounded-real certificate: the identity at level g in the solve's coordinates
        cl = s.hinf_shifted.transformed(pt.T_hinf[i]).scaled_output(pt.g_member[i])
        eigs["bounded_real"] = _max_eig(_bmi(*_brl_parts(cl, np.eye(cl.N), pt.Om, 1.0)))
        # back to the original coordinates x = Tc xt, Tc = blkdiag(T_state, I) T_rec, and
        # time t (P -> P / w0); at level g the certificate is g I in the solve's coordinates
        Tci = np.linalg.inv(sla.block_diag(s.hinf_st.T, np.eye(nk)) @ pt.T_hinf[i])
        P = sym(Tci.T @ Tci) * pt.g_member[i] / w0
        A, B, C, D = _Affine(m.hinf, nk).matrices(Om)
        gamma = hinf_norm(control.ss(A, B, C, D))
        gamma_sh = hinf_norm(control.ss(A + region.decay_rate * np.eye(A.shape[0]), B, C, D))
        Q = Z = None
        h2 = h2b = 0.0
        if s.h2 is not None:
            cl2 = s.h2.transformed(pt.T_h2[i])
            nz = cl2.C0.shape[0]
            Zs = np.eye(nz) * pt.z_member[i] / nz
            eigs["h2_state"] = _max_eig(_bmi(*_h2_parts(cl2, np.eye(cl2.N), pt.Om)))
            eigs["h2_output"] = -float(
                np.linalg.eigvalsh(sym(_h2_output(cl2, np.eye(cl2.N), pt.Om, Zs))).min()
            )
            # Q and Z in the solve's coordinates (plant states balanced, time tau = w0 t)
            Q, Z = np.eye(cl2.N), Zs
            h2b = math.sqrt(pt.z_member[i] * w0)
            h2 = h2_norm(*_Affine(m.h2, nk).matrices(Om)[:3])
        rc = None
        violation = region.worst_violation(np.linalg.eigvals(_Affine(m.region, nk).matrices(Om)[0]))
        if with_regions:
            rc = _region_certificate(
                m, s, pt.Om, nk, w0, region, solvers, solve_times, i, violation
            )
        elif not violation < 0:
            raise VerificationError(
                f"pksyn_multi: member {name}: a closed-loop pole lies outside the region "
                f"(violation {violation:.3g} rad/s)"
            )
        failed = {k: e for k, e in eigs.items() if e >= 0}
        if failed:
            raise VerificationError(
                f"pksyn_multi: member {name} fails the re-check of its certificates: {failed}"
            )
        if gamma_sh > pt.g_member[i] * (1 + 1e-6) or (s.h2 is not None and h2 > h2b * (1 + 1e-6)):
            raise VerificationError(
                f"pksyn_multi: member {name}: independent norms exceed the certified bounds "
                f"(shifted H-infinity {gamma_sh:.6g} vs {pt.g_member[i]:.6g}, H2 {h2:.6g} vs "
                f"{h2b:.6g})"
            )
        out.append(
            MemberCertificates(
                region=rc,
                P=P,
                Q=Q,
                Z=Z,
                lmi_max_eig=eigs,
                gamma=gamma,
                gamma_bound=pt.g_member[i],
                gamma_shifted=gamma_sh,
                h2=h2,
                h2_bound=h2b,
                region_violation=violation if rc is None else rc.violation,
            )
        )
    return out
