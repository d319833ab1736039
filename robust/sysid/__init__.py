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
from robust.sysid.experiment import (
    ENGINE_TONES_HZ,
    PAPER_COMPONENTS,
    ChirpProtocol,
    Experiment,
    MeasurementNoise,
    chirp_excitation,
    paper_experiment,
    select_path,
    simulate_experiment,
    simulate_response,
)
from robust.sysid.fit import (
    FORMS,
    BandError,
    FitResult,
    RationalParams,
    coherence_threshold,
    fit_frequency_response,
    form_system,
    levy_sk,
    parse_form,
)
from robust.sysid.identify import Identification, identify_file, identify_records
from robust.sysid.model_file import (
    ComponentFit,
    load_component_fit,
    read_component_fit,
    save_component_fit,
)
from robust.sysid.plots import bode_figure, coherence_figure
from robust.sysid.spectral import (
    FrequencyResponseEstimate,
    check_band,
    default_nperseg,
    effective_averages,
    estimate_frequency_response,
    estimate_frequency_responses,
)

__all__ = [
    "ENGINE_TONES_HZ",
    "FORMS",
    "PAPER_COMPONENTS",
    "BandError",
    "ChannelData",
    "ChirpProtocol",
    "ComponentFit",
    "Experiment",
    "FitResult",
    "FrequencyResponseEstimate",
    "Identification",
    "MeasurementNoise",
    "RationalParams",
    "bode_figure",
    "check_band",
    "chirp_excitation",
    "coherence_figure",
    "coherence_threshold",
    "default_nperseg",
    "effective_averages",
    "estimate_frequency_response",
    "estimate_frequency_responses",
    "fit_frequency_response",
    "form_system",
    "identify_file",
    "identify_records",
    "levy_sk",
    "load_channels",
    "load_component_fit",
    "paper_experiment",
    "parse_form",
    "read_component_fit",
    "save_component_fit",
    "save_experiment",
    "select_channels",
    "select_path",
    "simulate_experiment",
    "simulate_response",
]
