"""The one chunk loop (run_over_profile): chunked = one-shot, bit for bit."""

from dataclasses import replace

from gyro_emulator.emulation import profiles
from gyro_emulator.emulation.recorded_profile import RecordedProfile
from gyro_emulator.emulation.run_profile import (chunk_edges, fault_injector, join_chunks,
                                                 OnClock, OwnSamples, run_over_profile)
from gyro_emulator.emulation.truth.drawn import draw_profile
from gyro_emulator.sensor import faults
from gyro_emulator.sensor.config import load_sensor_config
from gyro_emulator.sensor.model import GyroModel
import numpy as np
import pytest

RATE_HZ = 100.0
CHUNK_SIZES = (1, 7, 256, 777, 4096)
SCHEDULE = (faults.Fault('bias_step', 'z', 0.02, 3.0, 2.0),
            faults.Fault('noise_burst', 'x', 0.05, 6.0, 1.5),
            faults.Fault('dropout', 'all', 0.0, 9.0, 0.5))


def _run(timeline_of, chunk_samples, config='consumer', with_faults=False, **kw):
    """Run a fresh seeded model; return the chunks and the model."""
    if isinstance(config, str):
        config = load_sensor_config(config)
    rng = np.random.default_rng(21)
    model = GyroModel(config, RATE_HZ, rng)
    injector = fault_injector(SCHEDULE, config, rng) if with_faults else None
    chunks = list(run_over_profile(model, timeline_of(model), chunk_samples, injector, **kw))
    return chunks, model


def _assert_same_run(whole, parts):
    """Every field of the joined chunks is identical, bit for bit."""
    a, b = join_chunks(whole), join_chunks(parts)
    assert np.array_equal(a[0], b[0])
    for name in ('rate_rad_s', 'temp_c', 'accel_m_s2'):
        assert np.array_equal(getattr(a[1], name), getattr(b[1], name)), name
    for name in a[2].__dataclass_fields__:
        assert np.array_equal(getattr(a[2], name), getattr(b[2], name)), name
    published = [np.concatenate([c.published for c in chunks]) if chunks[0].published
                 is not None else None for chunks in (whole, parts)]
    assert (published[0] is None) == (published[1] is None)
    if published[0] is not None:
        assert np.array_equal(published[0], published[1])


@pytest.mark.parametrize('with_faults', [False, True])
def test_on_the_clock_chunked_equals_one_shot(with_faults):
    steps = profiles.make_profile('steps', 12.0)

    def clock(model):
        return OnClock(steps, 1200, model.sample_period_s)

    whole, _ = _run(clock, 1200, with_faults=with_faults)
    assert len(whole) == 1 and len(whole[0].time_s) == 1200
    if with_faults:
        assert (~whole[0].published).sum() == 50          # the 0.5 s dropout at 100 Hz
    for size in CHUNK_SIZES:
        parts, _ = _run(clock, size, with_faults=with_faults)
        assert len(parts) == -(-1200 // size)
        _assert_same_run(whole, parts)


def test_a_record_on_the_model_grid_chunked_equals_one_shot():
    t = np.concatenate([np.arange(300) * 0.01, [2.995, 2.995, 3.0], 4.0 + np.arange(200) * 0.01])
    n = len(t)
    rate = np.column_stack([np.zeros(n), np.sin(t), np.full(n, 0.3)])
    record = RecordedProfile('log', t, rate, np.linspace(20.0, 30.0, n),
                             np.tile(profiles.LEVEL_ACCEL_M_S2, (n, 1)))

    def grid(model):
        return record.on_model_grid(model.sample_period_s)

    whole, _ = _run(grid, 10 ** 6, with_faults=True)
    # every record sample has its own grid sample, at the record's time (the
    # repeated stamp too); the grid samples of the 1 s gap are withheld
    assert np.array_equal(whole[0].time_s[whole[0].published], t)
    assert len(whole[0].time_s) == 601
    for size in CHUNK_SIZES:
        parts, _ = _run(grid, size, with_faults=True)
        _assert_same_run(whole, parts)


def test_own_samples_with_a_config_schedule_equal_the_pieces_run_by_hand():
    prof = draw_profile('thermal_cycle', np.random.default_rng(5), RATE_HZ, duration_s=30.0)
    config = load_sensor_config('consumer')
    schedule = {0: config,
                1234: replace(config, turn_on_bias_rad_s=(0.0, 0.0, 0.01)),
                2500: replace(config, scale_factor_error=(0.0, 0.0, 0.002))}
    by_hand = GyroModel(config, RATE_HZ, np.random.default_rng(21))
    expected = []
    for lo, hi in ((0, 1234), (1234, 2500), (2500, len(prof.time_s))):
        by_hand.update_config(schedule[lo])
        expected.append(by_hand.run(prof.rate_rad_s[lo:hi], prof.temp_c[lo:hi],
                                    prof.accel_m_s2[lo:hi]).gyro_rad_s)
    expected = np.concatenate(expected)
    for size in (len(prof.time_s), 1000, 333, 1):
        chunks, _ = _run(lambda model: OwnSamples(prof), size, configs=schedule)
        assert np.array_equal(np.concatenate([c.batch.gyro_rad_s for c in chunks]), expected)
        assert all(c.published is None for c in chunks)


def test_without_specific_force_the_model_gets_none():
    prof = profiles.static_profile(5.0, 30.0)
    config = replace(load_sensor_config('consumer'), g_sensitivity_rad_s_m_s2=(
        (0.0, 0.0, 1e-3), (0.0, 0.0, 1e-3), (0.0, 0.0, 1e-3))).with_terms(g_sensitivity=True)
    free = GyroModel(config, RATE_HZ, np.random.default_rng(21)).run(np.zeros((500, 3)), 30.0)
    for size in (500, 64):
        chunks, _ = _run(lambda model: OnClock(prof, 500, model.sample_period_s), size,
                         config=config, specific_force=False)
        assert np.array_equal(np.concatenate([c.batch.gyro_rad_s for c in chunks]),
                              free.gyro_rad_s)
    level, _ = _run(lambda model: OnClock(prof, 500, model.sample_period_s), 500, config=config)
    assert not np.array_equal(level[0].batch.gyro_rad_s, free.gyro_rad_s)


def test_chunk_edges_end_at_the_breaks():
    assert chunk_edges(10, 4) == [0, 4, 8, 10]
    assert chunk_edges(10, 4, {0: None, 5: None, 12: None}) == [0, 4, 5, 8, 10]
    assert chunk_edges(0, 4) == [0]
