"""The paper's claims C1-C5 (BRIEF section 4), each checked on a model variant.

Each check returns a :class:`ClaimResult` with a status (``"holds"``,
``"fails"`` or ``"not testable"``), the numbers behind it, and a one-paragraph
detail. A claim that fails is reported as failing; nothing here is tuned to pass.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from backhoe.analysis.calibration import K_PSF_STABLE
from backhoe.analysis.loops import bdft_loop_gain, bdft_ratio, critical_k_psf, loop_poles
from backhoe.model.components import K_PSF_NOMINAL
from backhoe.model.loop import BDFTLoop
from robust.checks import NONNEGATIVE, POSITIVE, check_vector
from robust.errors import ParameterError

__all__ = [
    "ClaimResult",
    "evaluate_claims",
    "CLAIM_TEXT",
    "WORKSPACE_FACTORS",
    "RATIO_FREQS_HZ",
    "ratio_study",
]

CLAIM_TEXT = {
    "C1": "At nominal K_PSF (0.1097) the closed loop has exactly two unstable poles.",
    "C2": "At K_PSF = 0.055 (workspace doubled) the closed loop is stable.",
    "C3": "For workspace factors 2..10 the loop is stable and the with/without-BDFT output ratio "
    "(Figure 13) shrinks toward 1 as the workspace grows.",
    "C4": "BDFT matters mainly near the structure's natural frequencies (about 6 Hz) and has no "
    "significant effect below about 1 Hz.",
    "C5": "The Omni's fore-aft position (+-4 in) barely changes transmission to the hand.",
}

#: Workspace factors of the paper's Figure 13 study.
WORKSPACE_FACTORS = tuple(range(2, 11))
#: Frequency grid (Hz) of the ratio study; log-spaced, 0.05-20 Hz.
RATIO_FREQS_HZ = np.geomspace(0.05, 20.0, 600)
#: C4 thresholds: "no significant effect" below 1 Hz means within this many dB of 1.
C4_LOW_BAND_HZ = 1.0
C4_LOW_TOL_DB = 1.0
#: C4: "near the structure's natural frequencies" means the peak deviation lies in this
#: band (Hz).
C4_PEAK_BAND_HZ = (4.0, 9.0)


@dataclasses.dataclass(frozen=True)
class ClaimResult:
    """Verdict on one of the paper's claims, with the numbers behind it.

    Parameters
    ----------
    claim : str
        Claim label, ``"C1"`` to ``"C5"`` (its statement is ``CLAIM_TEXT[claim]``).
    status : {"holds", "fails", "not testable"}
        The verdict; ``"not testable"`` when the model variant lacks what the claim
        needs (e.g. C5 without a handle-position parameter).
    detail : str
        One paragraph explaining the verdict in words and numbers, for reports.
    numbers : dict
        The quantities the verdict rests on (pole locations in rad/s, frequencies
        in Hz, deviations in dB, keyed by name; per workspace factor where the
        claim sweeps it); empty when there are none. Values may be numpy or complex
        numbers (convert with :func:`robust.jsonio.to_jsonable`).
    """

    claim: str
    status: str  # "holds" | "fails" | "not testable"
    detail: str
    numbers: dict

    @property
    def holds(self) -> bool:
        """Whether ``status`` is ``"holds"``."""
        return self.status == "holds"

    def to_json(self) -> dict:
        """``holds``, ``status``, ``detail`` and ``numbers`` as a dict (``claim`` omitted)."""
        return {
            "holds": self.holds,
            "status": self.status,
            "detail": self.detail,
            "numbers": self.numbers,
        }


def _hz(p) -> float:
    return float(abs(np.imag(p)) / (2 * np.pi))


def ratio_study(loop: BDFTLoop, factors=WORKSPACE_FACTORS, freqs_hz=RATIO_FREQS_HZ) -> dict:
    """Figure 13: |Y_bdft / Y_nobdft| in dB for each workspace factor, with stability.

    Parameters
    ----------
    loop : BDFTLoop
        The loop at its own ``k_psf``; each member has ``K_PSF = loop.k_psf / factor``.
    factors : iterable of float, optional
        Workspace factors; :data:`WORKSPACE_FACTORS` (2 to 10) by default.
    freqs_hz : numpy.ndarray, optional
        Frequency grid in Hz, shape (F,); :data:`RATIO_FREQS_HZ` (600 log-spaced
        points over 0.05-20 Hz) by default. Must include frequencies below 1 Hz.

    Returns
    -------
    dict
        Workspace factor to a dict with ``k_psf``, ``stable`` (bool),
        ``max_real_pole`` (rad/s), ``ratio_db`` (shape (F,)), ``peak_dev_db`` (the
        largest ``|ratio_db|``), ``peak_freq_hz`` (where it occurs) and
        ``low_band_dev_db`` (the largest ``|ratio_db|`` below 1 Hz). The ratio is
        computed whether or not the member is stable; it is only meaningful when it
        is.

    Raises
    ------
    ParameterError
        If ``loop`` is not a :class:`~backhoe.model.loop.BDFTLoop`, ``factors`` is not a
        non-empty sequence of finite positive numbers, or ``freqs_hz`` is not a
        non-empty 1-D array of finite frequencies >= 0 with one below 1 Hz.
    """
    if not isinstance(loop, BDFTLoop):
        raise ParameterError(f"ratio_study: loop must be a BDFTLoop; got {type(loop).__name__}")
    if isinstance(factors, (str, bytes)) or not hasattr(factors, "__iter__"):
        raise ParameterError(
            f"ratio_study: factors must be a sequence of workspace factors; got {factors!r}"
        )
    factors = list(factors)
    check_vector("ratio_study: factors", factors, POSITIVE)
    freqs_hz = check_vector("ratio_study: freqs_hz", freqs_hz, NONNEGATIVE)
    if not np.any(freqs_hz < C4_LOW_BAND_HZ):
        raise ParameterError(
            f"ratio_study: freqs_hz must include frequencies below {C4_LOW_BAND_HZ:g} Hz; "
            f"got {freqs_hz.min():g} Hz and up"
        )
    rows = {}
    for fac in factors:
        member = loop.with_workspace_factor(fac)
        ps = loop_poles(member)
        db = 20 * np.log10(np.abs(bdft_ratio(member, freqs_hz)))
        dev = np.abs(db)
        low = freqs_hz < C4_LOW_BAND_HZ
        rows[fac] = dict(
            k_psf=member.k_psf,
            stable=ps.stable,
            max_real_pole=ps.max_real,
            ratio_db=db,
            peak_dev_db=float(dev.max()),
            peak_freq_hz=float(freqs_hz[dev.argmax()]),
            low_band_dev_db=float(dev[low].max()),
        )
    return rows


def evaluate_claims(loop: BDFTLoop, *, study: dict | None = None) -> dict[str, ClaimResult]:
    """Check C1-C5 on ``loop`` (its ``k_psf`` is ignored: the claims fix their own).

    Parameters
    ----------
    loop : BDFTLoop
        The model variant: components, human and calibration. C1 is checked at
        ``K_PSF = 0.1097``, C2 and C4's loop gain at ``K_PSF = 0.055``, C3 and C4 on
        the workspace factors of ``study``; C5 needs a human with a
        ``with_handle_offset`` method and is "not testable" otherwise.
    study : dict, optional
        The output of :func:`ratio_study` on ``loop``, to reuse one already
        computed; computed with the default factors and grid when omitted.

    Returns
    -------
    dict of str to ClaimResult
        ``"C1"`` to ``"C5"`` in order.

    Raises
    ------
    ParameterError
        If ``loop`` is not a :class:`~backhoe.model.loop.BDFTLoop` or ``study`` is not a dict.
    """
    if not isinstance(loop, BDFTLoop):
        raise ParameterError(f"evaluate_claims: loop must be a BDFTLoop; got {type(loop).__name__}")
    if study is not None and not isinstance(study, dict):
        raise ParameterError(
            f"evaluate_claims: study must be the dict of ratio_study; got {type(study).__name__}"
        )
    res = {}
    nominal = loop.replace(k_psf=K_PSF_NOMINAL)
    ps = loop_poles(nominal)
    k_crit = critical_k_psf(nominal)
    unst = ps.unstable_poles
    res["C1"] = ClaimResult(
        "C1",
        "holds" if ps.n_unstable == 2 else "fails",
        f"{ps.n_unstable} unstable pole(s) at K_PSF={K_PSF_NOMINAL}"
        + (
            f": {', '.join(f'{p.real:+.3f}{p.imag:+.3f}j' for p in unst)} rad/s "
            f"({_hz(unst[0]):.2f} Hz)"
            if unst.size
            else ""
        )
        + f"; stability is lost at K_PSF={k_crit:.4g}"
        + (
            f"; {ps.hidden.size} hidden mode(s) at |s|<={np.abs(ps.hidden).max():.1e} removed "
            "(Eqn 4 s^2 x Eqn 5 1/s^2)"
            if ps.hidden.size
            else ""
        ),
        dict(
            n_unstable=ps.n_unstable,
            unstable_poles=[complex(p) for p in unst],
            unstable_freq_hz=[_hz(p) for p in unst],
            k_psf_critical=k_crit,
            n_hidden_modes=int(ps.hidden.size),
        ),
    )
    ps2 = loop_poles(loop.replace(k_psf=K_PSF_STABLE))
    res["C2"] = ClaimResult(
        "C2",
        "holds" if ps2.stable else "fails",
        f"max real part of the closed-loop poles at K_PSF={K_PSF_STABLE}: "
        f"{ps2.max_real:+.4f} rad/s "
        f"({'stable' if ps2.stable else f'{ps2.n_unstable} unstable'})",
        dict(max_real_pole=ps2.max_real, n_unstable=ps2.n_unstable),
    )
    study = study if study is not None else ratio_study(loop)
    facs = sorted(study)
    stable_all = all(study[f]["stable"] for f in facs)
    peaks = [study[f]["peak_dev_db"] for f in facs]
    shrinking = all(b <= a + 1e-9 for a, b in zip(peaks, peaks[1:]))
    res["C3"] = ClaimResult(
        "C3",
        "holds" if stable_all and shrinking else "fails",
        f"factors {facs[0]}..{facs[-1]}: {'all stable' if stable_all else 'NOT all stable'}; "
        f"peak |ratio| deviation {peaks[0]:.2f} dB (x{facs[0]}) -> "
        f"{peaks[-1]:.2f} dB (x{facs[-1]}), "
        f"{'monotonically shrinking' if shrinking else 'not monotonic'}",
        dict(
            stable={f: study[f]["stable"] for f in facs},
            max_real_pole={f: study[f]["max_real_pole"] for f in facs},
            peak_dev_db={f: study[f]["peak_dev_db"] for f in facs},
            peak_freq_hz={f: study[f]["peak_freq_hz"] for f in facs},
        ),
    )
    stable_facs = [f for f in facs if study[f]["stable"]]
    if not stable_facs:
        res["C4"] = ClaimResult(
            "C4", "fails", "no workspace factor 2..10 is stable; the ratio is undefined", {}
        )
    else:
        in_band = [
            C4_PEAK_BAND_HZ[0] <= study[f]["peak_freq_hz"] <= C4_PEAK_BAND_HZ[1]
            for f in stable_facs
        ]
        low_ok = [study[f]["low_band_dev_db"] <= C4_LOW_TOL_DB for f in stable_facs]
        worst_low = max(study[f]["low_band_dev_db"] for f in stable_facs)
        ok = all(in_band) and all(low_ok)
        # diagnosis: where is the loop gain of the BDFT path largest? (at the
        # workspace-doubled K_PSF)
        diag_f = np.array([0.5, 1.0, 2.0, np.sqrt(loop.struct.f1_hz * loop.struct.f2_hz)])
        lg = np.abs(bdft_loop_gain(loop.replace(k_psf=K_PSF_STABLE), diag_f)["loop"])
        why = []
        if not all(in_band):
            bad = [
                f"x{f}: {study[f]['peak_freq_hz']:.2f} Hz"
                for f, b in zip(stable_facs, in_band)
                if not b
            ]
            why.append(
                f"peak deviation outside {C4_PEAK_BAND_HZ[0]:g}-{C4_PEAK_BAND_HZ[1]:g} Hz "
                f"({', '.join(bad[:3])})"
            )
        if not all(low_ok):
            why.append(
                f"deviation below {C4_LOW_BAND_HZ:g} Hz reaches {worst_low:.2f} dB "
                f"(> {C4_LOW_TOL_DB:g} dB)"
            )
        res["C4"] = ClaimResult(
            "C4",
            "holds" if ok else "fails",
            (
                f"over stable factors {stable_facs[0]}..{stable_facs[-1]} the ratio peaks at "
                f"{study[stable_facs[0]]['peak_freq_hz']:.2f} Hz (x{stable_facs[0]}) "
                "and deviates at most "
                f"{worst_low:.2f} dB below {C4_LOW_BAND_HZ:g} Hz"
            )
            + ("" if ok else "; fails: " + "; ".join(why))
            + f"; BDFT loop gain at K_PSF={K_PSF_STABLE}: {lg[1]:.3g} at 1 Hz "
            f"vs {lg[3]:.3g} at the "
            f"structure mode ({diag_f[3]:.2f} Hz)",
            dict(
                loop_gain_at_hz={float(f): float(g) for f, g in zip(diag_f, lg)},
                peak_freq_hz={f: study[f]["peak_freq_hz"] for f in stable_facs},
                low_band_dev_db={f: study[f]["low_band_dev_db"] for f in stable_facs},
                peak_band_hz=list(C4_PEAK_BAND_HZ),
                low_band_tol_db=C4_LOW_TOL_DB,
            ),
        )
    res["C5"] = _claim_c5(loop)
    return res


def _claim_c5(loop: BDFTLoop) -> ClaimResult:
    human = loop.human
    offset = getattr(human, "with_handle_offset", None)
    if offset is None:
        return ClaimResult(
            "C5",
            "not testable",
            f"the {human.variant!r} human model has no handle-position parameter, so the "
            "effect of moving the Omni +-4 in cannot be computed; the paper's evidence (its "
            "Figure 10) is a LifeMOD simulation that is not available here",
            {},
        )
    freqs = np.geomspace(1.0, 10.0, 200)
    base = _hand_response(human, freqs)
    devs = {}
    for dx in (-0.1016, 0.1016):
        devs[f"{dx:+.4f} m"] = float(
            np.max(np.abs(20 * np.log10(np.abs(_hand_response(offset(dx), freqs) / base))))
        )
    worst = max(devs.values())
    return ClaimResult(
        "C5",
        "holds" if worst <= 3.0 else "fails",
        f"moving the handle +-4 in changes |H/C| over 1-10 Hz by at most {worst:.2f} dB "
        "(threshold 3 dB)",
        dict(max_change_db=devs, threshold_db=3.0),
    )


def _hand_response(human, freqs_hz):
    sys = human.system()
    w = 2 * np.pi * freqs_hz
    return np.asarray(sys(1j * w, squeeze=False))[
        sys.output_labels.index("h"), sys.input_labels.index("c"), :
    ]
