"""
The diagnosis as typed, frozen values, and its JSON (:func:`to_json`).

:func:`.document.build` makes a :class:`Diagnosis` once, where the verdict
is decided: its verdict and message are final when it is made. Export,
report and command line read its attributes; :func:`to_json` is the one
place that turns it into the JSON document of ``diagnose --json`` (keys,
their order and values as the command has always written them).

Sequences are tuples and plain mappings read-only, so nothing edits a
diagnosis after it is made. Field names are the JSON keys (but
:attr:`Diagnosis.record`, the JSON ``input``); a field whose metadata says
``omit_none`` is left out of the JSON while it is None.
"""

from dataclasses import dataclass, field, fields, is_dataclass
from types import MappingProxyType

import numpy as np

_OMIT_NONE = {'omit_none': True}


def frozen_mapping(mapping):
    """Return a read-only copy of ``mapping`` (insertion order kept)."""
    return MappingProxyType(dict(mapping))


@dataclass(frozen=True)
class Parameter:
    """
    One fitted parameter: value, 1-sigma, unit, meaning, 95 % interval and how it was found.

    ``interval`` is None (and ``sigma`` None) for a coefficient the record
    cannot measure (:mod:`.intervals`); ``method`` says which estimate
    (jackknife over the folds, the sandwich under the record's noise law,
    or profile likelihood for a searched one).
    """

    value: float
    sigma: float
    unit: str
    meaning: str
    interval: tuple = None
    method: str = None


@dataclass(frozen=True)
class Evidence:
    """What a cause's significance rests on: the test, its p-values and which gain."""

    route: str
    p_fold_test: float
    p_state_space: float
    likelihood_ratio: float
    gain_predictive: float
    #: The gain the decision rests on: 'gain_predictive' or 'gain_step'.
    gain: str


@dataclass(frozen=True)
class OwnTempco:
    """
    A part's own relative SF slope at T_ref: c1 plus the physics' R'(T_ref) (1/K).

    ``interval`` is its 95 % interval; ``compensated`` the comparison of
    that interval with a stated datasheet figure (``datasheet_per_k``,
    named in ``datasheet``; :func:`.document.own_tempco`).
    """

    value: float
    sigma: float
    physics_per_k: float
    meaning: str
    compensated: bool
    interval: tuple = None
    datasheet_per_k: float = None
    datasheet: str = None


@dataclass(frozen=True)
class Cause:
    """
    A chosen cause: its parameters, held-out gains, evidence and what it cannot be told from.

    ``parameters`` maps each parameter name to its :class:`Parameter`;
    ``part_sf_temp_coeff_per_k`` is given for ``scale_factor_temperature``
    against the paper's physics only.
    """

    effect: str
    cause: str
    kind: str
    parameters: MappingProxyType
    rmse_rad_s: float
    gain: float
    gain_step: float
    gain_binned: float
    p_value: float
    evidence: Evidence
    delta_bic: float
    effective_bins: float
    noise_share_of_gain: float
    indistinguishable_from: tuple
    rmse_interval_rad_s: tuple
    gain_interval: tuple
    mechanisms: tuple
    competitors: tuple
    part_sf_temp_coeff_per_k: OwnTempco = field(default=None, metadata=_OMIT_NONE)
    #: Whether the cause's 95 % interval excludes zero (``explained`` needs it).
    interval_excludes_zero: bool = None
    #: Where that interval includes zero and the cause has two or more measured
    #: coefficients: the p-value that they are zero together, Hotelling's T^2
    #: over the folds (the size rule's joint test; omitted otherwise).
    joint_p_value: float = field(default=None, metadata=_OMIT_NONE)


@dataclass(frozen=True)
class Finding:
    """A candidate of the first selection step (the ``findings`` table)."""

    effect: str
    cause: str
    kind: str
    parameters: MappingProxyType
    rmse_rad_s: float
    gain: float
    gain_over_recalibrated: float
    gain_binned: float
    p_value: float
    evidence: Evidence
    delta_bic: float
    n_params: int
    significant: bool
    in_sample_only: str = None


@dataclass(frozen=True)
class Candidate:
    """A candidate of one selection step, scored against the model of that step."""

    effect: str
    rmse_rad_s: float
    gain_step: float
    gain_binned: float
    p_value: float
    route: str
    p_state_space: float
    delta_bic: float
    significant: bool
    in_sample_only: str = None


@dataclass(frozen=True)
class InSampleOnly:
    """A cause the tests support in-sample that held-out data do not confirm: never chosen."""

    effect: str
    p_value: float
    gain_step: float
    gain_binned: float
    reason: str


@dataclass(frozen=True)
class Bound:
    """What the data rule out: a 95 % upper bound on a cause tested and not found."""

    effect: str
    quantity: str
    upper: float
    unit: str


@dataclass(frozen=True)
class Step:
    """One forward-selection step: the cause it added (None: nothing) and its candidates."""

    added: str
    candidates: tuple


@dataclass(frozen=True)
class NotTested:
    """A cause the record cannot show, and why."""

    effect: str
    reason: str


@dataclass(frozen=True)
class Confound:
    """Two regressors that move together: no fit can separate them."""

    a: str
    b: str
    correlation: float


@dataclass(frozen=True)
class ConfoundedPair:
    """A bias that follows temperature or time where the record cannot say which."""

    correlation: float
    bias_temp_coeff_rad_s_k: float
    bias_drift_rad_s_per_h: float
    experiment: str
    text: str


@dataclass(frozen=True)
class RecordSummary:
    """The record diagnosed: its source, size, span, sampling, bins and channels."""

    source: str
    rows: int
    duration_s: float
    time_span_s: tuple
    sample_interval_s: float
    bins: int
    bin_s: float
    temp_range_c: tuple
    has_temp: bool
    rate_rms_rad_s: float
    has_accel: bool
    recovery: tuple


@dataclass(frozen=True)
class Baseline:
    """The user-calibrated baseline: held-out RMSE, its interval, the model it is."""

    rmse_rad_s: float
    rmse_interval_rad_s: tuple
    model: str
    #: Held-out RMSE of the baseline recalibrated on all training data (JSON
    #: ``recalibrated_baseline``).
    recalibrated_rmse_rad_s: float


@dataclass(frozen=True)
class SetAside:
    """The samples screening set aside as outliers, and what counting them would change."""

    count: int
    fraction: float
    segments: tuple
    segments_total: int
    threshold_sigma: float
    sigma_rad_s: float
    baseline_rmse_all_samples_rad_s: float
    best_gain_all_samples: float


@dataclass(frozen=True)
class Follows:
    """The regressor the averaged residual follows most, against noise alone."""

    regressor: str
    r2: float
    r2_limit: float
    margin: float


@dataclass(frozen=True)
class Suggestive:
    """A candidate suggestive but not established: its gain and uncorrected p."""

    effect: str
    gain: float
    p_value: float


@dataclass(frozen=True)
class Residual:
    """
    What the chosen causes leave, against the record's noise floor, and the verdict's message.

    ``noise`` is the final residual's :class:`.noise_model.NoiseModel`,
    ``r2`` the group R^2 per regressor (read-only mapping).
    """

    rms_rad_s: float
    floor_rad_s: float
    excess: float
    excess_limit: float
    averaging_s: float
    excess_slow: float
    excess_slow_limit: float
    follows: Follows
    consistent: bool
    wander_measured_to_s: float
    noise: object
    r2: MappingProxyType
    strongest_correlate: str
    structure_remains: bool
    excess_over_noise: float
    noise_rad_s: float
    message: str
    causes_tested: tuple
    suggestive: Suggestive


@dataclass(frozen=True)
class TemperaturePolynomial:
    """The order of the temperature polynomials the record carries, and why."""

    order: int
    span_k: float
    note: str


@dataclass(frozen=True)
class Method:
    """The selection rules and constants the diagnosis ran with."""

    folds: int
    sub_blocks: int
    alpha: float
    alpha_tie: float
    min_gain: float
    min_gain_rate: float
    delta_bic_max: float
    outlier_threshold_sigma: float
    null_simulations: int
    rmse: str
    test: str
    information_criterion: str
    uncertainty: str
    blocks: str


@dataclass(frozen=True)
class ResidualPlots:
    """What the report plots: the bins, the residual before and after, the final model's name."""

    prepared: object
    before: np.ndarray
    after: np.ndarray
    after_label: str


@dataclass(frozen=True)
class Diagnosis:
    """
    Everything ``diagnose`` found (:func:`gyro_emulator.analysis.diagnose.diagnose`).

    ``record`` is the JSON ``input``; ``calibration`` is the baseline's
    :class:`.baseline.Calibration` on the whole record; ``config`` the
    sensor configuration of the baseline (None: the paper physics of
    ``device_preset``); ``plots`` what the report draws (not in the JSON).
    """

    record: RecordSummary
    device_preset: str
    calibration: object
    baseline: Baseline
    set_aside: SetAside
    selected: tuple
    verdict: str
    residual: Residual
    confounded: tuple
    confounded_pair: ConfoundedPair
    experiments: tuple
    findings: tuple
    steps: tuple
    not_tested: tuple
    method: Method
    temperature_polynomial: TemperaturePolynomial
    config: str = None
    plots: ResidualPlots = None
    #: Causes the tests support in-sample that held-out data do not confirm.
    supported_in_sample: tuple = ()
    #: 95 % upper bounds on the causes tested and not found (:mod:`.ruled_out`).
    ruled_out: tuple = ()
    #: The noise of a second record of the part, held fixed in the null
    #: (``--reference``; :mod:`.reference`), or None.
    reference: object = None

    @property
    def best(self):
        """Return the first chosen cause, or None."""
        return self.selected[0] if self.selected else None


def _plain(value):
    """Return ``value`` as JSON-ready Python values (dataclasses by field, tuples as lists)."""
    if is_dataclass(value):
        if hasattr(value, 'as_dict'):
            return value.as_dict()
        return {f.name: _plain(getattr(value, f.name)) for f in fields(value)
                if not (f.metadata.get('omit_none') and getattr(value, f.name) is None)}
    if isinstance(value, (tuple, list)):
        return [_plain(v) for v in value]
    if isinstance(value, (dict, MappingProxyType)):
        return {k: _plain(v) for k, v in value.items()}
    return value


def _best(diagnosis):
    """Return the JSON ``best``: the first chosen cause (or ``none``) with its all-sample gain."""
    gain_all = diagnosis.set_aside.best_gain_all_samples
    cause = diagnosis.best
    if cause is None:
        return {'effect': 'none', 'cause': None, 'kind': None, 'parameters': {},
                'rmse_rad_s': diagnosis.baseline.rmse_rad_s, 'gain': 0.0, 'p_value': None,
                'indistinguishable_from': [], 'gain_all_samples': gain_all}
    out = _plain(cause)
    own = out.pop('part_sf_temp_coeff_per_k', None)
    out['gain_all_samples'] = gain_all
    if own is not None:
        out['part_sf_temp_coeff_per_k'] = own
    return out


def to_json(diagnosis):
    """
    Return the JSON document of ``diagnosis`` (what ``diagnose --json`` writes).

    Top level: ``input``, ``device_preset``, ``calibration``, ``baseline``,
    ``recalibrated_baseline``, ``set_aside``, ``best``, ``selected``,
    ``verdict``, ``residual``, ``confounded``, ``confounded_pair``,
    ``experiments``, ``findings`` (the first step's candidates, ranked),
    ``steps``, ``not_tested``, ``ruled_out`` (95 % upper bounds on the
    causes tested and not found), ``supported_in_sample`` (causes the tests
    support that held-out data do not confirm), ``method``,
    ``temperature_polynomial`` and, for a baseline from a sensor
    configuration, ``config``; with ``--reference``, ``reference``. ``best`` is the
    first chosen cause with its gain counted on every sample
    (``effect: 'none'`` when none is).
    """
    d = diagnosis
    baseline = _plain(d.baseline)
    recalibrated = {'rmse_rad_s': baseline.pop('recalibrated_rmse_rad_s')}
    doc = {'input': _plain(d.record), 'device_preset': d.device_preset,
           'calibration': d.calibration.as_dict(), 'baseline': baseline,
           'recalibrated_baseline': recalibrated, 'set_aside': _plain(d.set_aside),
           'best': _best(d), 'selected': _plain(d.selected), 'verdict': d.verdict,
           'residual': _plain(d.residual), 'confounded': _plain(d.confounded),
           'confounded_pair': _plain(d.confounded_pair), 'experiments': list(d.experiments),
           'findings': _plain(d.findings), 'steps': _plain(d.steps),
           'not_tested': _plain(d.not_tested), 'ruled_out': _plain(d.ruled_out),
           'supported_in_sample': _plain(d.supported_in_sample), 'method': _plain(d.method),
           'temperature_polynomial': _plain(d.temperature_polynomial)}
    if d.config is not None:
        doc['config'] = d.config
    if d.reference is not None:
        doc['reference'] = _plain(d.reference)
    return doc
