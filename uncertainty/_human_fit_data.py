"""Stored result of :func:`uncertainty.fit_human.run_fit` (generated; do not edit by hand).

Regenerate with ``python -m uncertainty.fit_human --write``.
"""

FIT_RESULT = {'settings': {'band_hz': [1.0, 10.0],
              'body_mass_kg': 75.0,
              'c_bounds': [1.0, 3000.0],
              'k_bounds': [10.0, 100000.0],
              'n_freq': 120,
              'n_starts': 24,
              'seed': 20240},
 'three_dof': {'at_bounds': ['c1'],
               'dampings': [180.03852429612218, 1.0, 6.121225020868422],
               'err_db_max': 11.465016662758938,
               'err_db_rms': 4.640178246130244,
               'err_deg_max': 114.26211259665901,
               'err_deg_rms': 71.88467585615226,
               'gain': 24.087890954974387,
               'masses': [47.1, 2.1, 1.65],
               'stiffnesses': [44542.669880886286, 302.8234445918469, 160.24609563939552]},
 'two_dof': {'at_bounds': [],
             'dampings': [184.76468428574853, 3.2982494226834898],
             'err_db_max': 11.626891366432996,
             'err_db_rms': 4.906337156121328,
             'err_deg_max': 116.71378574896383,
             'err_deg_rms': 71.31186635652107,
             'gain': 24.326150436311327,
             'masses': [47.1, 3.7499999999999996],
             'stiffnesses': [10343.219352450376, 207.52028759468672]}}
