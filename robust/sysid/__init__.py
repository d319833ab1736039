"""System identification from chirp data: experiments, H1 and coherence, structured fits.

The paper's path from measured chirp responses to component models, for any
machine or operator:

* experiments (:mod:`.experiment`): chirp protocol and a simulator with known truth;
* spectra (:mod:`.spectral`): Welch H1 (the paper's Eqn 1), coherence (Eqn 2) and
  confidence bounds;
* fits (:mod:`.fit`): the forms (:mod:`.forms`) of Eqns 3, 4, 5 and rational
  ``"M/N"`` models, started by Levy / Sanathanan-Koerner (:mod:`.linear`);
* data files (:mod:`.datafile`) and fitted-model files (:mod:`.model_file`);
* figures (:mod:`.plots`), returned and never saved here.
"""

from robust.sysid.datafile import ChannelData, load_channels, save_experiment, select_channels
from robust.sysid.spectral import (
    FrequencyResponseEstimate,
    check_band,
    default_nperseg,
    effective_averages,
    estimate_frequency_response,
    estimate_frequency_responses,
)

__all__ = [
    "ChannelData",
    "FrequencyResponseEstimate",
    "check_band",
    "default_nperseg",
    "effective_averages",
    "estimate_frequency_response",
    "estimate_frequency_responses",
    "load_channels",
    "save_experiment",
    "select_channels",
]
