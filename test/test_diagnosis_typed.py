"""
The typed diagnosis (issue 31 item 1): frozen values, one JSON.

``test/data/diagnosis_*.json`` are the documents ``diagnose`` writes for two
seeded truth records (first those of the untyped diagnosis; rewritten once
when issue 33 gave every parameter an interval and added ``ruled_out`` and
``supported_in_sample``, and for ``sf_tempco`` when a shape in time was
carried into an end fold only on evidence beyond the noise, and again when
that evidence was asked of two origins next to the end fold: the held-out
figures of ``scale_factor_time`` and the order the candidates rank in;
and when one function came to compute every sandwich sigma, which moved
the last digits of the sigmas, intervals and bounds, none by more than
1e-9 of its value; and when the search for a cause's parameters came to
weigh the SSE with the ridge of the final fit: ``viscosity_temperature``'s
figures at the second step and its ruled-out share, 7.71 to 7.77 %; and when
a delay's interval became the union over the applied rate's shapes between
its samples: ``time_delay``'s interval and bound, 2.85 to 2.94 ms at the
top): :func:`to_json` must give them back byte for byte.
"""

from dataclasses import FrozenInstanceError
import functools
import json
import os

from gyro_emulator.analysis.diagnose import diagnose, Diagnosis, to_json
from gyro_emulator.analysis.diagnose import diagnosis as dg
from gyro_emulator.emulation.truth.generator import make_truth
import pytest

DATA = os.path.join(os.path.dirname(os.path.abspath(__file__)), 'data')
#: Seeded truth records and the document the untyped diagnosis wrote for each.
CASES = {'sf_tempco': {'effect': 'electronics_sf_tempco', 'seed': 5},
         'none_static': {'effect': 'none', 'seed': 1, 'profile': 'static', 'duration_s': 600}}


@functools.lru_cache(maxsize=None)
def _diagnosis(name):
    """Return the diagnosis of case ``name``: made once, shared by the tests (it is frozen)."""
    record, _ = make_truth(**CASES[name])
    return diagnose(record)


@pytest.mark.parametrize('name', sorted(CASES))
def test_to_json_gives_the_document_of_the_untyped_diagnosis(name):
    diagnosis = _diagnosis(name)
    assert isinstance(diagnosis, Diagnosis)
    with open(os.path.join(DATA, f'diagnosis_{name}.json'), encoding='utf-8') as handle:
        old = handle.read()
    # as `diagnose --json` writes it: the same keys, in the same order, the same values
    assert json.dumps(to_json(diagnosis), indent=1, default=float) == old
    assert json.loads(json.dumps(to_json(diagnosis), default=float)) == json.loads(old)


def test_the_typed_fields_are_what_the_json_says():
    diagnosis = _diagnosis('sf_tempco')
    doc = to_json(diagnosis)
    cause = diagnosis.best
    assert cause is diagnosis.selected[0] and cause.effect == doc['best']['effect']
    assert doc['best']['gain_all_samples'] == diagnosis.set_aside.best_gain_all_samples
    assert cause.part_sf_temp_coeff_per_k.value == doc['best']['part_sf_temp_coeff_per_k'][
        'value']
    for name, p in cause.parameters.items():
        assert doc['selected'][0]['parameters'][name] == {
            'value': p.value, 'sigma': p.sigma, 'unit': p.unit, 'meaning': p.meaning,
            'interval': list(p.interval), 'method': p.method}
        assert p.interval[0] < p.value < p.interval[1]       # never +- 0 (issue 33)
    assert [b.effect for b in diagnosis.ruled_out] == [b['effect'] for b in doc['ruled_out']]
    assert diagnosis.residual.message == doc['residual']['message']
    assert diagnosis.record.rows == doc['input']['rows']
    assert diagnosis.baseline.recalibrated_rmse_rad_s == doc['recalibrated_baseline'][
        'rmse_rad_s']
    assert 'config' not in doc and diagnosis.config is None


def test_the_diagnosis_refuses_to_be_edited():
    diagnosis = _diagnosis('sf_tempco')
    cause = diagnosis.selected[0]
    with pytest.raises(FrozenInstanceError):
        diagnosis.verdict = 'explained'
    with pytest.raises(FrozenInstanceError):
        diagnosis.residual.message = 'edited'
    with pytest.raises(FrozenInstanceError):
        cause.mechanisms = ()
    with pytest.raises(FrozenInstanceError):
        cause.evidence.route = 'fold_test'
    with pytest.raises(FrozenInstanceError):
        next(iter(cause.parameters.values())).value = 0.0
    with pytest.raises(TypeError):
        cause.parameters['sf_temp_coeff_per_k'] = None       # a read-only mapping
    with pytest.raises(TypeError):
        diagnosis.residual.r2['time'] = 1.0
    with pytest.raises(AttributeError):
        diagnosis.selected.append(cause)                      # a tuple
    with pytest.raises(FrozenInstanceError):
        dg.Confound('a', 'b', 0.9).correlation = 0.0
