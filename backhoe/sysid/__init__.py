"""Identification of the machine's and the operator's components from chirp data.

The paper's path from measured chirp responses to component models, built on the generic
spectra and rational fits of :mod:`robust.sysid`:

* experiments (:mod:`.experiment`): chirp protocol and a simulator with known truth;
* fits (:mod:`.fit`): the forms (:mod:`.forms`) of Eqns 3, 4, 5 and rational
  ``"M/N"`` models, started by Levy / Sanathanan-Koerner (:mod:`robust.sysid.linear`);
* fitted-model files (:mod:`.model_file`) and the identification of a data file
  (:mod:`.identify`);
* figures (:mod:`.plots`), returned and never saved here.
"""

from backhoe.sysid.experiment import (
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
from backhoe.sysid.fit import (
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
from backhoe.sysid.identify import Identification, identify_file, identify_records
from backhoe.sysid.model_file import (
    ComponentFit,
    load_component_fit,
    read_component_fit,
    save_component_fit,
)
from backhoe.sysid.plots import bode_figure, coherence_figure

__all__ = [
    "ENGINE_TONES_HZ",
    "PAPER_COMPONENTS",
    "ChirpProtocol",
    "Experiment",
    "MeasurementNoise",
    "chirp_excitation",
    "paper_experiment",
    "select_path",
    "simulate_experiment",
    "simulate_response",
    "FORMS",
    "BandError",
    "FitResult",
    "RationalParams",
    "coherence_threshold",
    "fit_frequency_response",
    "form_system",
    "levy_sk",
    "parse_form",
    "Identification",
    "identify_file",
    "identify_records",
    "ComponentFit",
    "load_component_fit",
    "read_component_fit",
    "save_component_fit",
    "bode_figure",
    "coherence_figure",
]
