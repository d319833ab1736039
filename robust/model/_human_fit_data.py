"""Stored result of :func:`robust.model.human_fit.run_fit` (generated; do not edit by hand).

Regenerate with ``python -m robust.model.human_fit --write``.
"""

FIT_RESULT = {
    "settings": {
        "band_hz": [1.0, 10.0],
        "body_mass_kg": 75.0,
        "c_bounds": [1.0, 3000.0],
        "k_bounds": [10.0, 100000.0],
        "n_freq": 120,
        "n_starts": 24,
        "n_starts_3dof": 96,
        "seed": 20240,
    },
    "three_dof": {
        "at_bounds": ["c2"],
        "dampings": [120.24243862024967, 2.1789659679593827, 1.0],
        "err_db_max": 8.558431914852791,
        "err_db_rms": 3.7093666086817865,
        "err_deg_max": 176.60639239650249,
        "err_deg_rms": 81.55937417949913,
        "gain": 18.48563681528298,
        "masses": [47.1, 2.1, 1.65],
        "stiffnesses": [8040.906110193632, 258.48195261882944, 191.04442159181787],
    },
    "two_dof": {
        "at_bounds": [],
        "dampings": [184.76468428574853, 3.2982494226834898],
        "err_db_max": 11.626891366432996,
        "err_db_rms": 4.906337156121328,
        "err_deg_max": 116.71378574896383,
        "err_deg_rms": 71.31186635652107,
        "gain": 24.326150436311327,
        "masses": [47.1, 3.7499999999999996],
        "stiffnesses": [10343.219352450376, 207.52028759468672],
    },
}
