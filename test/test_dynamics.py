"""Exact 2-DOF response, time domain and rate-channel envelope (Eq 3-4)."""

from dataclasses import replace

import dynamics_reference
from gyro_emulator.physics import dynamics, first_order, time_domain
from gyro_emulator.physics.presets import PAPER_DEVICE, PAPER_SUTHERLAND_DEVICE
from gyro_emulator.units import deg_s_to_rad_s
import numpy as np
import pytest
from scipy import linalg, signal

RATE = float(deg_s_to_rad_s(60.0))


# --- exact steady state -----------------------------------------------------

@pytest.mark.parametrize('device', [PAPER_DEVICE, PAPER_SUTHERLAND_DEVICE],
                         ids=['paper', 'sutherland'])
def test_matched_exact_agrees_with_first_order(device):
    rates = deg_s_to_rad_s(np.array([-300.0, -60.0, -1.0, 0.5, 60.0, 300.0]))
    temps = np.array([[-40.0], [25.0], [85.0]])
    exact = dynamics.exact_steady_state(device, rates, temps)
    first = first_order.first_order_response(device, rates, temps)
    np.testing.assert_allclose(exact.sense_amplitude_m, first.sense_amplitude_m,
                               rtol=1e-4)
    np.testing.assert_allclose(exact.drive_amplitude_m,
                               np.broadcast_to(first.drive_amplitude_m, (3, 6)),
                               rtol=1e-4)
    np.testing.assert_allclose(exact.ratio_to_first_order, 1.0, rtol=1e-4)
    # Coriolis response in quadrature with the drive velocity: all in-phase.
    np.testing.assert_allclose(exact.sense_phase_rad, np.pi / 2, atol=1e-9)
    np.testing.assert_allclose(exact.sense_in_phase_m, exact.sense_amplitude_m,
                               rtol=1e-9)
    assert np.all(np.abs(exact.sense_quadrature_m)
                  <= 1e-9 * np.abs(exact.sense_amplitude_m))


def test_exact_solves_the_equations_of_motion():
    """Cramer's closed form against a numerical solve of the 2x2 system."""
    splits = np.array([-700.0, -50.0, 0.0, 20.0, 300.0])
    drive = np.array([13500.0, 14000.0, 14400.0])[:, None]
    temp = 60.0
    rate = 7.0  # large, so the back-action is visible in the solve
    ex = dynamics.exact_steady_state(PAPER_DEVICE, rate, temp, splits, drive)
    p = first_order.lumped_parameters(PAPER_DEVICE, temp)
    m, w = p.mass_kg, 2 * np.pi * drive[:, 0]
    for i, wi in enumerate(w):
        for j, split in enumerate(splits):
            k_y = m * (2 * np.pi * (p.freq_x_hz + split)) ** 2
            mat = np.array([
                [p.stiffness_x_n_m - m * wi ** 2 + 1j * wi * p.damping_drive_n_s_m,
                 -2j * m * rate * wi],
                [2j * m * rate * wi,
                 k_y - m * wi ** 2 + 1j * wi * p.damping_sense_n_s_m]])
            x, y = np.linalg.solve(mat, [-1j * p.drive_force_n, 0.0])
            assert ex.drive_amplitude_m[i, j] == pytest.approx(abs(x), rel=1e-12)
            assert ex.sense_amplitude_m[i, j] == pytest.approx(abs(y), rel=1e-12)
            assert ex.sense_in_phase_m[i, j] == pytest.approx(y.real, rel=1e-12)
            assert ex.sense_quadrature_m[i, j] == pytest.approx(-y.imag, rel=1e-12)


def test_split_costs_what_physics_md_says():
    splits = np.array([10.0, 50.0, 100.0, 500.0])
    ex = dynamics.exact_steady_state(PAPER_DEVICE, RATE, 25.0, splits)
    loss = 1.0 - ex.ratio_to_first_order
    # docs/physics.md: about 4-5 % at 50 Hz, 15 % at 100 Hz, 70 % at 500 Hz.
    assert loss[0] < 0.005
    assert 0.04 <= loss[1] <= 0.05
    assert 0.14 <= loss[2] <= 0.17
    assert 0.67 <= loss[3] <= 0.73
    q_s, f_x = ex.params.q_sense, ex.params.freq_x_hz
    approx = 1.0 / np.sqrt(1.0 + (2 * q_s * splits / f_x) ** 2)
    np.testing.assert_allclose(ex.ratio_to_first_order, approx, rtol=0.02)
    # A split detunes whichever way it goes.
    neg = dynamics.exact_steady_state(PAPER_DEVICE, RATE, 25.0, -splits)
    np.testing.assert_allclose(neg.ratio_to_first_order, approx, rtol=0.05)


def test_exact_is_vectorised_elementwise():
    rates = np.array([-1.0, 0.0, 2.0])[:, None]
    splits = np.array([0.0, 40.0, -120.0, 500.0])
    temps = np.array([0.0, 25.0, 50.0, 120.0])
    ex = dynamics.exact_steady_state(PAPER_DEVICE, rates, temps, splits)
    assert ex.sense_amplitude_m.shape == (3, 4)
    for i in range(3):
        for j in range(4):
            one = dynamics.exact_steady_state(PAPER_DEVICE, rates[i, 0], temps[j],
                                              splits[j])
            assert ex.sense_amplitude_m[i, j] == pytest.approx(
                float(one.sense_amplitude_m), rel=1e-13, abs=0.0)
            assert ex.ratio_to_first_order[i, j] == pytest.approx(
                float(one.ratio_to_first_order), rel=1e-13)
    assert np.all(ex.sense_amplitude_m[1] == 0.0)
    assert np.all(np.sign(ex.sense_amplitude_m[0]) == -1.0)


# --- time domain --------------------------------------------------------------

@pytest.mark.parametrize('split,temp,samples', [
    (0.0, 25.0, 8), (100.0, 25.0, 8), (-300.0, 85.0, 3), (37.0, -20.0, 16)])
def test_time_domain_steady_state_matches_exact(split, temp, samples):
    settle = dynamics.settle_time_s(PAPER_DEVICE, temp)
    res = dynamics.simulate_time_domain(PAPER_DEVICE, settle, RATE, temp, split,
                                        samples_per_cycle=samples, initial='rest')
    ex = dynamics.exact_steady_state(PAPER_DEVICE, RATE, temp, split)
    amp = float(ex.sense_amplitude_m)
    assert res.sense_amplitude_m[-1] == pytest.approx(amp, rel=1e-4)
    assert res.in_phase_m[-1] == pytest.approx(float(ex.sense_in_phase_m),
                                               rel=1e-4, abs=1e-4 * amp)
    assert res.quadrature_m[-1] == pytest.approx(float(ex.sense_quadrature_m),
                                                 rel=1e-4, abs=1e-4 * amp)
    assert res.drive_amplitude_m[-1] == pytest.approx(
        float(ex.drive_amplitude_m), rel=1e-4)
    # Far from steady state at the start (from rest).
    assert abs(res.sense_amplitude_m[0]) < 0.2 * abs(amp)


def test_time_domain_off_resonance_drive_matches_exact():
    drive_hz = float(first_order.lumped_parameters(PAPER_DEVICE, 50.0).freq_x_hz) + 60.0
    settle = dynamics.settle_time_s(PAPER_DEVICE, 50.0)
    res = dynamics.simulate_time_domain(PAPER_DEVICE, settle, -RATE, 50.0, 40.0,
                                        drive_freq_hz=drive_hz)
    ex = dynamics.exact_steady_state(PAPER_DEVICE, -RATE, 50.0, 40.0, drive_hz)
    assert res.drive_freq_hz[-1] == pytest.approx(drive_hz, rel=1e-12)
    assert res.sense_amplitude_m[-1] == pytest.approx(float(ex.sense_amplitude_m),
                                                      rel=1e-4)
    assert res.drive_amplitude_m[-1] == pytest.approx(float(ex.drive_amplitude_m),
                                                      rel=1e-4)
    # Off resonance the drive amplitude drops below Eq 15's X_drive, as a
    # resonator detuned by 60 Hz does: 1 / sqrt(1 + (2 Q_d df / f)^2).
    first = first_order.first_order_response(PAPER_DEVICE, 0.0, 50.0)
    q_d, f_x = float(first.params.q_drive), float(first.params.freq_x_hz)
    assert float(ex.drive_amplitude_m / first.drive_amplitude_m) == pytest.approx(
        1.0 / np.hypot(1.0, 2 * q_d * 60.0 / f_x), rel=0.01)


def test_time_domain_transient_matches_dop853():
    """The exact per-cycle map against scipy's DOP853 (rtol 1e-12)."""
    duration = 0.002
    res = dynamics.simulate_time_domain(PAPER_DEVICE, duration, 3.0, 25.0, 100.0,
                                        initial='rest')
    ref = dynamics_reference.simulate_reference(PAPER_DEVICE, duration, 3.0, 25.0, 100.0)
    n = len(res.time_s)
    assert ref.shape == (n + 1, 4)
    w = 2 * np.pi * float(first_order.lumped_parameters(PAPER_DEVICE).freq_x_hz)
    scale = np.array([1.0, w, 1.0, w]) * np.max(np.abs(ref[:, [0, 0, 2, 2]]), 0)
    err = np.max(np.abs(ref[:n] - res.state_m), 0) / scale
    assert np.all(err < 1e-9), err


def test_cycle_series_matches_direct_exponential():
    """The power series in Omega against scipy's expm of A(Omega) h."""
    mech = time_domain._mechanics(PAPER_DEVICE, 40.0, 120.0, None)
    w0 = 2 * np.pi * 13000.0
    h = 1.0 / mech.drive_freq_hz
    for rate in (0.3, -20.0, 150.0):
        order = time_domain._series_order(abs(rate) * h)
        phi_k, g_k, _, _ = time_domain._cycle_maps(mech, w0, order, 8)
        powers = (rate * h) ** np.arange(order + 1)
        a = np.zeros((6, 6))
        m = mech.mass
        a[0, 1], a[2, 3] = w0, w0
        a[1, 0], a[3, 2] = -mech.k_x / (m * w0), -mech.k_y / (m * w0)
        a[1, 1], a[3, 3] = -mech.c_d / m, -mech.c_s / m
        a[1, 3], a[3, 1] = 2 * rate, -2 * rate
        a[1, 5] = 1 / (m * w0)
        w = 2 * np.pi * mech.drive_freq_hz
        a[4, 5], a[5, 4] = -w, w
        direct = linalg.expm(a * h)
        np.testing.assert_allclose(np.tensordot(powers, phi_k, 1), direct[:4, :4],
                                   atol=1e-11)
        np.testing.assert_allclose(np.tensordot(powers, g_k, 1), direct[:4, 4],
                                   rtol=1e-10, atol=1e-12 * np.abs(direct[:4, 4]).max())


def test_rate_profile_and_drive_frequency_follow_inputs():
    res = dynamics.simulate_time_domain(
        PAPER_DEVICE, 0.01, lambda t: 2.0 * t, lambda t: 25.0 + 6000.0 * t,
        temp_update_s=0.001)
    np.testing.assert_allclose(res.rate_rad_s, 2.0 * res.time_s)
    assert res.temp_c[0] == 25.0 and res.temp_c[-1] == pytest.approx(79.0, abs=1.0)
    f_end = first_order.lumped_parameters(PAPER_DEVICE, res.temp_c[-1]).freq_x_hz
    assert res.drive_freq_hz[-1] == pytest.approx(float(f_end), rel=1e-12)
    assert np.all(np.diff(res.time_s) > 0)
    assert res.time_s[-1] + res.period_s[-1] / 2 >= 0.01


def test_agc_holds_amplitude_when_temperature_changes():
    ramp = 0.1

    def temp(t):
        return 25.0 + 60.0 * min(t, ramp) / ramp

    runs = {mode: dynamics.simulate_time_domain(
        PAPER_DEVICE, 0.15, RATE, temp, drive=mode, temp_update_s=0.002)
        for mode in dynamics.DRIVE_MODES}
    target = float(first_order.first_order_response(PAPER_DEVICE, 0.0).drive_amplitude_m)
    agc, open_loop = runs['agc'], runs['open_loop']
    assert agc.temp_c[-1] == 85.0
    # Open loop: the drive amplitude follows the damping (Eq 15), +2 % here.
    x85 = float(dynamics.exact_steady_state(PAPER_DEVICE, RATE, 85.0).drive_amplitude_m)
    assert x85 / target - 1 > 0.01
    assert open_loop.drive_amplitude_m[-1] == pytest.approx(x85, rel=1e-4)
    # AGC: held throughout the ramp and exactly once settled.
    assert np.max(np.abs(agc.drive_amplitude_m / target - 1)) < 1e-3
    assert agc.drive_amplitude_m[-1] == pytest.approx(target, rel=1e-5)
    assert agc.drive_force_n[-1] < 0.99 * agc.drive_force_n[0]
    # The rate output then matches the exact solution with the AGC's force.
    ex = dynamics.exact_steady_state(PAPER_DEVICE, RATE, 85.0,
                                     drive_force_n=agc.drive_force_n[-1])
    assert agc.in_phase_m[-1] == pytest.approx(float(ex.sense_in_phase_m), rel=1e-4)


def test_agc_settles_from_rest_to_its_set_point():
    agc = dynamics.AgcSettings(amplitude_m=5e-6, bandwidth_hz=100.0, update_cycles=1)
    res = dynamics.simulate_time_domain(PAPER_DEVICE, 0.08, 0.0, 40.0, drive='agc',
                                        agc=agc, initial='rest')
    assert res.drive_amplitude_m[0] < 1e-6
    assert res.drive_amplitude_m[-1] == pytest.approx(5e-6, rel=1e-6)
    assert np.max(res.drive_force_n) <= 10 * float(
        first_order.lumped_parameters(PAPER_DEVICE).drive_force_n) * (1 + 1e-12)


# --- envelope (reduced-order) rate channel -----------------------------------

@pytest.mark.parametrize('split', [0.0, 50.0, 100.0, 500.0, -200.0])
def test_envelope_step_response_matches_time_domain(split):
    res = dynamics.simulate_time_domain(PAPER_DEVICE, 0.008,
                                        lambda t: RATE * (t > 0.0), 25.0, split)
    gain = float(dynamics.exact_steady_state(PAPER_DEVICE, RATE, 25.0,
                                             split).sense_in_phase_m)
    td = res.in_phase_m / gain
    env = dynamics.rate_channel_step_response(PAPER_DEVICE, res.time_s, 25.0, split)
    assert np.max(np.abs(td - env)) < 0.02
    assert abs(td[-1] - 1.0) < 0.02


@pytest.mark.parametrize('split', [0.0, 100.0, 500.0])
@pytest.mark.parametrize('freq', [20.0, 160.0, 400.0])
def test_envelope_frequency_response_matches_time_domain(split, freq):
    h_td = dynamics.time_domain_frequency_response(PAPER_DEVICE, freq, 25.0, split)
    h_env = dynamics.rate_channel_frequency_response(PAPER_DEVICE, freq, 25.0, split)
    assert abs(h_td - h_env) < 0.02 * abs(h_env)


def test_matched_rate_channel_is_a_first_order_lag():
    p = first_order.lumped_parameters(PAPER_DEVICE)
    w_y = 2 * np.pi * float(p.freq_y_hz)
    tau = 2 * float(p.q_sense) / w_y
    assert 0.9e-3 < tau < 1.1e-3
    poles = dynamics.rate_channel_poles(PAPER_DEVICE)
    assert 1.0 / poles.sigma_1_s == pytest.approx(tau, rel=1e-12)
    assert abs(poles.delta_rad_s) < 1e-2 * poles.sigma_1_s
    bw = dynamics.rate_channel_bandwidth_hz(PAPER_DEVICE)
    assert bw == pytest.approx(float(p.freq_y_hz) / (2 * float(p.q_sense)), rel=1e-3)
    assert 150.0 < bw < 170.0
    assert abs(dynamics.rate_channel_frequency_response(PAPER_DEVICE, bw)) == \
        pytest.approx(2 ** -0.5, rel=1e-9)
    t = np.array([tau, 3 * tau])
    np.testing.assert_allclose(dynamics.rate_channel_step_response(PAPER_DEVICE, t),
                               1 - np.exp(-t / tau), atol=1e-4)


@pytest.mark.parametrize('split', [100.0, 500.0])
def test_split_rate_channel_is_a_complex_pair_at_the_split(split):
    poles = dynamics.rate_channel_poles(PAPER_DEVICE, 25.0, split)
    assert poles.delta_rad_s / (2 * np.pi) == pytest.approx(split, rel=0.02)
    bw = dynamics.rate_channel_bandwidth_hz(PAPER_DEVICE, 25.0, split)
    assert bw > dynamics.rate_channel_bandwidth_hz(PAPER_DEVICE)
    assert abs(dynamics.rate_channel_frequency_response(
        PAPER_DEVICE, bw, 25.0, split)) == pytest.approx(2 ** -0.5, rel=1e-9)


@pytest.mark.parametrize('split,rate_hz', [(0.0, 1000.0), (150.0, 200.0),
                                           (-500.0, 4000.0)])
def test_rate_channel_discrete_is_exact_zoh_with_unit_dc_gain(split, rate_hz):
    a, b, c, d = dynamics.rate_channel_state_space(PAPER_DEVICE, 30.0, split)
    assert (c @ np.linalg.solve(-a, b) + d)[0, 0] == pytest.approx(1.0, rel=1e-12)
    ad, bd, cd, dd = dynamics.rate_channel_discrete(PAPER_DEVICE, rate_hz, 30.0, split)
    ref = signal.cont2discrete((a, b, c, d), 1.0 / rate_hz, method='zoh')
    np.testing.assert_allclose(ad, ref[0], rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(bd, ref[1], rtol=1e-12, atol=1e-14)
    dc = cd @ np.linalg.solve(np.eye(2) - ad, bd) + dd
    assert dc[0, 0] == pytest.approx(1.0, rel=1e-12)


@pytest.mark.parametrize('split', [0.0, 100.0])
@pytest.mark.parametrize('rate_hz', [100.0, 1000.0, 4000.0])
def test_sampled_rate_channel_matches_the_time_domain_at_its_instants(split, rate_hz):
    """A sample reflects the rate at its own instant: no one-sample delay (2-DOF reference)."""
    disc = dynamics.rate_channel_discrete(PAPER_DEVICE, rate_hz, 25.0, split)
    gain = float(dynamics.exact_steady_state(PAPER_DEVICE, RATE, 25.0,
                                             split).sense_in_phase_m)
    t_n = np.arange(0.0, 0.025, 1.0 / rate_hz)
    # a rate step just after sample 0: the Eq 3-4 output at every later instant
    res = dynamics.simulate_time_domain(PAPER_DEVICE, 0.03, lambda t: RATE * (t > 0.0),
                                        25.0, split)
    out, _ = dynamics.rate_channel_filter(disc, (t_n > 0.0).astype(float))
    td = np.interp(t_n, res.time_s, res.in_phase_m / gain)
    assert np.max(np.abs(out - td)[1:]) < 1e-3
    # a 20 Hz rate: within the continuous model's own lag (2 pi f / sigma) of Eq 3-4
    freq = 20.0
    res = dynamics.simulate_time_domain(
        PAPER_DEVICE, 0.03, lambda t: RATE * np.sin(2 * np.pi * freq * t), 25.0, split)
    out, _ = dynamics.rate_channel_filter(disc, np.sin(2 * np.pi * freq * t_n))
    td = np.interp(t_n, res.time_s, res.in_phase_m / gain)
    sigma = dynamics.rate_channel_poles(PAPER_DEVICE, 25.0, split).sigma_1_s
    assert np.max(np.abs(out - td)[t_n > 0.005]) < 2 * np.pi * freq / sigma


def test_rate_channel_filter_matches_per_sample_steps():
    disc = dynamics.rate_channel_discrete(PAPER_DEVICE, 2000.0, 25.0, 80.0)
    rng = np.random.default_rng(3)
    u = rng.normal(size=300)
    x0 = np.array([0.2, -0.1])
    out, final = dynamics.rate_channel_filter(disc, u, x0)
    x, loop = x0, []
    for value in u:
        x, y = dynamics.rate_channel_step(disc, x, value)
        loop.append(y)
    np.testing.assert_allclose(out, loop, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(final, x, rtol=1e-12, atol=1e-12)
    # Continuing from the final state equals one long run.
    out2, _ = dynamics.rate_channel_filter(disc, u[150:], dynamics.rate_channel_filter(
        disc, u[:150], x0)[1])
    np.testing.assert_allclose(out2, out[150:], rtol=1e-12, atol=1e-12)


def test_rate_channel_bandwidth_follows_sense_damping():
    """Thinner gas (1 kPa) lowers C_sense and the bandwidth with it (Eq 9-11)."""
    thin = replace(PAPER_DEVICE, gas=replace(PAPER_DEVICE.gas, pressure_pa=1000.0))
    ratio = (first_order.lumped_parameters(thin).damping_sense_n_s_m
             / first_order.lumped_parameters(PAPER_DEVICE).damping_sense_n_s_m)
    assert ratio < 0.5
    assert dynamics.rate_channel_bandwidth_hz(thin) / dynamics.rate_channel_bandwidth_hz(
        PAPER_DEVICE) == pytest.approx(float(ratio), rel=1e-3)


# --- errors -------------------------------------------------------------------

@pytest.mark.parametrize('call,field', [
    (lambda: dynamics.exact_steady_state(PAPER_DEVICE, 1.0, split_hz=-2e4),
     'split_hz'),
    (lambda: dynamics.exact_steady_state(PAPER_DEVICE, np.nan), 'rate_rad_s'),
    (lambda: dynamics.exact_steady_state(PAPER_DEVICE, 1.0, drive_freq_hz=0.0),
     'drive_freq_hz'),
    (lambda: dynamics.exact_steady_state(PAPER_DEVICE, 1.0, temp_c=500.0), 'temp_c'),
    (lambda: dynamics.simulate_time_domain(PAPER_DEVICE, 0.01, drive='pll'), 'drive'),
    (lambda: dynamics.simulate_time_domain(PAPER_DEVICE, -1.0), 'duration_s'),
    (lambda: dynamics.simulate_time_domain(PAPER_DEVICE, 0.01, samples_per_cycle=2),
     'samples_per_cycle'),
    (lambda: dynamics.simulate_time_domain(PAPER_DEVICE, 0.01, samples_per_cycle=4.5),
     'samples_per_cycle'),
    (lambda: dynamics.simulate_time_domain(PAPER_DEVICE, 0.01, np.ones(3)),
     'rate_rad_s'),
    (lambda: dynamics.simulate_time_domain(PAPER_DEVICE, 0.01, lambda t: t * np.inf),
     'rate_rad_s'),
    (lambda: dynamics.simulate_time_domain(PAPER_DEVICE, 0.01, 0.0, lambda t: 900.0),
     'temp_c'),
    (lambda: dynamics.AgcSettings(bandwidth_hz=-5.0), 'bandwidth_hz'),
    (lambda: dynamics.AgcSettings(update_cycles=2.5), 'update_cycles'),
    (lambda: dynamics.rate_channel_discrete(PAPER_DEVICE, 0.0), 'sample_rate_hz'),
    (lambda: dynamics.rate_channel_state_space(PAPER_DEVICE, np.array([1.0, 2.0])),
     'temp_c'),
])
def test_bad_input_names_the_field(call, field):
    with pytest.raises(ValueError, match=field):
        call()
