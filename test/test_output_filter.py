"""The twin's output filter: a part's digital low-pass identified from the PSD of its noise."""

from gyro_emulator.analysis.calibrate import export_noise, lowpass
from gyro_emulator.analysis.calibrate.noise import calibrate_noise
from gyro_emulator.emulation import simulate
from gyro_emulator.recording.record import Record
import numpy as np
import pytest
from scipy import signal

RATE_HZ = 100.0
N_RAD_S_SQRT_HZ = 1e-3
SAMPLES = 200_000


def _record(seed, order=None, cutoff_hz=None):
    """White rate noise of density N, through a Butterworth low-pass when given."""
    rng = np.random.default_rng(seed)
    y = rng.standard_normal(SAMPLES) * N_RAD_S_SQRT_HZ * np.sqrt(RATE_HZ)
    if order is not None:
        b, a = signal.butter(order, cutoff_hz, fs=RATE_HZ)
        y = signal.lfilter(b, a, y, zi=signal.lfilter_zi(b, a) * y[0])[0]
    return Record.from_arrays(np.arange(SAMPLES) / RATE_HZ, y, path=f'seed {seed}')


def _adev(y, m):
    """Overlapping Allan deviation of a contiguous series at tau = m / RATE_HZ."""
    theta = np.cumsum(y) / RATE_HZ
    d = theta[2 * m:] - 2.0 * theta[m:-m] + theta[:-2 * m]
    return float(np.sqrt(np.mean(d ** 2) / 2.0) / (m / RATE_HZ))


@pytest.mark.parametrize('order,cutoff_hz', [(2, 20.0), (1, 12.0), (2, 35.0)])
def test_the_low_pass_of_a_part_is_found_from_its_psd(order, cutoff_hz):
    cal = calibrate_noise(_record(7, order, cutoff_hz))
    found = lowpass.identify_output_filter(cal)
    assert found is not None and found.order == order
    # the cut-off carries the error of the fitted N (about 1.5 % at 1 sigma here), which
    # it compensates at the short taus: over 8 seeds it fell within 6 % of the truth
    assert found.cutoff_hz == pytest.approx(cutoff_hz, rel=0.08)
    assert found.explained > 0.95
    assert 'Butterworth' in found.describe()


def test_white_noise_gets_no_filter():
    # false alarms over independent records of white noise
    found = [lowpass.identify_output_filter(calibrate_noise(_record(seed)))
             for seed in range(10)]
    assert sum(f is not None for f in found) == 0


def test_the_twin_with_its_filter_follows_the_log_at_the_shortest_taus():
    record = _record(11, 2, 20.0)
    cal = calibrate_noise(record)
    fields = export_noise.twin_noise(cal)
    assert 'output_filter' in fields.terms_on
    config = export_noise.twin_config(fields)
    assert config.terms.output_filter and config.output_filter_order == 2
    assert config.output_filter_hz == pytest.approx(20.0, rel=0.08)
    text = export_noise.preset(cal)
    assert 'output_filter_hz:' in text and 'output_filter_order: 2' in text
    _, _, batch = simulate.run_simulation(config, 'static', SAMPLES / RATE_HZ, RATE_HZ, seed=3)
    twin = batch.gyro_rad_s[:, 0]
    log = record.gyro_axis('x')[0]
    for m in (1, 2):
        assert _adev(twin, m) == pytest.approx(_adev(log, m), rel=0.03)
    # without the filter the twin's white noise reads the shortest tau far too high
    plain = config.with_terms(output_filter=False)
    _, _, batch = simulate.run_simulation(plain, 'static', SAMPLES / RATE_HZ, RATE_HZ, seed=3)
    assert _adev(batch.gyro_rad_s[:, 0], 1) > 1.2 * _adev(log, 1)
