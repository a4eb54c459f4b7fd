"""
Beyond first order: exact 2-DOF response, time domain and rate-channel dynamics.

Everything here solves the paper's equations of motion in the rotating frame
(Patel & McCluskey, Eq 3-4; ``docs/physics.md``)::

    M x'' + C_d x' + k_x x = F sin(w t) + 2 M Omega y'          (Eq 3)
    M y'' + C_s y' + k_y y =            - 2 M Omega x'          (Eq 4)

with the lumped parameters of :func:`gyro_emulator.physics.first_order.lumped_parameters`
(Eq 5-12). A drive-sense frequency split keeps ``k_x`` and sets
``k_y = M (2 pi (f_x + split_hz))^2``. As in the paper, the centrifugal
(Omega^2) and angular-acceleration terms of the rotating frame are neglected.

Three models, from exact to cheap, each in its own module (this one gathers
their public names):

* :func:`exact_steady_state` (:mod:`.exact`) -- harmonic balance of Eq 3-4 including the
  Coriolis back-action on the drive (a complex 2x2 solve per frequency).
* :func:`simulate_time_domain` (:mod:`.time_domain`) -- Eq 3-4 in time with Omega(t), T(t), an
  open-loop or amplitude-regulated (AGC) drive and synchronous demodulation,
  discretised exactly (one matrix step per drive cycle).
* :func:`rate_channel_state_space` / :func:`rate_channel_discrete` (:mod:`.envelope`) -- the
  reduced-order (envelope) model of the rate channel, cheap enough to run per
  output sample in a node.

Demodulation convention (used by all three): the drive force is
``F sin(phi)``; the rate (in-phase) reference is ``cos(phi)`` and the
quadrature reference ``sin(phi)``. With matched modes and the drive at
resonance the sense motion is ``Y cos(phi)``, so the in-phase output equals
the first-order Y_sense (Eq 20, signed by the rate) and the quadrature is 0.
"""

from gyro_emulator.physics.envelope import (
    rate_channel_bandwidth_hz, rate_channel_discrete, rate_channel_filter,
    rate_channel_frequency_response, rate_channel_poles, rate_channel_state_space,
    rate_channel_step, rate_channel_step_response, RateChannelPoles)
from gyro_emulator.physics.exact import exact_steady_state, ExactSteadyState
from gyro_emulator.physics.time_domain import (
    AgcSettings, DRIVE_MODES, INITIAL_STATES, settle_time_s,
    simulate_time_domain, time_domain_frequency_response, TimeDomainResult)

__all__ = [
    'AgcSettings', 'DRIVE_MODES', 'exact_steady_state', 'ExactSteadyState', 'INITIAL_STATES',
    'rate_channel_bandwidth_hz', 'rate_channel_discrete', 'rate_channel_filter',
    'rate_channel_frequency_response', 'rate_channel_poles', 'rate_channel_state_space',
    'rate_channel_step', 'rate_channel_step_response', 'RateChannelPoles', 'settle_time_s',
    'simulate_time_domain', 'time_domain_frequency_response',
    'TimeDomainResult']
