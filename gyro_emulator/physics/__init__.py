"""
The physics core: device parameters, Eq 5-22 and the 2-DOF dynamics.

``params`` holds the frozen device dataclasses, ``first_order`` the paper's
lumped model and first-order response (Eq 5-21), ``dynamics`` the exact
harmonic steady state, the time-domain simulation and the rate-channel
envelope, ``presets`` the paper's device, ``paper`` the reproduction of
its Table 1 and figures, and ``kinematics`` the attitude and the specific
force. Imports numpy and scipy (and numba for the attitude loop) only.
"""
