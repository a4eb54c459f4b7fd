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
top; and when a continuous searched parameter's interval was widened as a
coefficient's: those intervals, their methods, and the ruled-out bounds
read from them; and when the causes already chosen came to take, from the
cause added last, what the training rows cannot tell apart
(:data:`.models.HELD_RIDGE`): ``sf_tempco``'s second step, its held-out
figures and the order its candidates rank in, and the ruled-out share of
the Sutherland law beside the SF tempco chosen, 7.7 to 12.5 %; the verdict
and the cause chosen are the same): :func:`to_json` must give them back, the same keys in the
same order and the same text. Its numbers are compared within
:data:`REL_TOL` (and :data:`ABS_TOL`), not bit for bit: the figures move
with the machine's floating point (numpy's SIMD exp and log, and the
optimizers' paths through them). On an AMD EPYC without AVX-512 the
documents written on the machine before it differed by up to 1.7 % of a
candidate's held-out gain (-2.887e-4 against -2.888e-4) and 0.73 % of a
ruled-out share, and in no key, order or text.
"""

from dataclasses import FrozenInstanceError
import functools
import json
import math
import os

from gyro_emulator.analysis.diagnose import diagnose, Diagnosis, to_json
from gyro_emulator.analysis.diagnose import diagnosis as dg
from gyro_emulator.emulation.truth.generator import make_truth
import pytest

DATA = os.path.join(os.path.dirname(os.path.abspath(__file__)), 'data')
#: Seeded truth records and the document the untyped diagnosis wrote for each.
CASES = {'sf_tempco': {'effect': 'electronics_sf_tempco', 'seed': 5},
         'none_static': {'effect': 'none', 'seed': 1, 'profile': 'static', 'duration_s': 600}}
#: How far a number of the document may move with the machine's floating point.
REL_TOL, ABS_TOL = 2e-2, 1e-6


def _differences(new, old, path=''):
    """Yield where ``new`` differs from ``old``: keys, order, lengths, text, or a number."""
    if isinstance(old, dict):
        if not isinstance(new, dict) or list(new) != list(old):
            yield f'{path}: keys {list(new)[:6]} against {list(old)[:6]}'
            return
        for key in old:
            yield from _differences(new[key], old[key], f'{path}.{key}')
    elif isinstance(old, list):
        if not isinstance(new, list) or len(new) != len(old):
            yield f'{path}: {new!r:.80} against {old!r:.80}'
            return
        for i, (a, b) in enumerate(zip(new, old)):
            yield from _differences(a, b, f'{path}[{i}]')
    elif isinstance(old, float) and isinstance(new, (int, float)) and \
            not isinstance(new, bool):
        if not math.isclose(new, old, rel_tol=REL_TOL, abs_tol=ABS_TOL):
            yield f'{path}: {new!r} against {old!r}'
    elif new != old or type(new) is not type(old):
        yield f'{path}: {new!r:.120} against {old!r:.120}'


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
    # as `diagnose --json` writes it: the same keys, in the same order, the same text
    # and the same numbers within what the machine's floating point moves
    new = json.loads(json.dumps(to_json(diagnosis), indent=1, default=float))
    assert list(_differences(new, json.loads(old))) == []


def test_the_document_comparison_sees_a_key_an_order_a_text_and_a_number():
    old = {'a': [1.0, 'x'], 'b': {'c': 0.5}}
    assert list(_differences(old, old)) == []
    assert list(_differences({'a': [1.001, 'x'], 'b': {'c': 0.5}}, old)) == []
    assert list(_differences({'b': {'c': 0.5}, 'a': [1.0, 'x']}, old)) != []
    assert list(_differences({'a': [1.0, 'y'], 'b': {'c': 0.5}}, old)) != []
    assert list(_differences({'a': [1.1, 'x'], 'b': {'c': 0.5}}, old)) != []
    assert list(_differences({'a': [1.0], 'b': {'c': 0.5}}, old)) != []


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
