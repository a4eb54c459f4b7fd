"""
Named physics presets: immutable module constants nobody mutates.

``paper`` is the geometry and constants of ``docs/physics.md`` that reproduce
Patel & McCluskey's Table 1; it is the default device everywhere. The other
presets change only the gas, to show what the paper's assumptions hide.
"""

from types import MappingProxyType

from gyro_emulator.physics.params import Device, Gas

#: The paper's device (Table 1): 1 atm air, constant viscosity, vented cavity.
PAPER_DEVICE = Device()

#: The paper's device with Sutherland's law for the air viscosity.
PAPER_SUTHERLAND_DEVICE = Device(gas=Gas(viscosity_law='sutherland'))

#: The paper's device sealed at 1 atm (constant number density), Sutherland air.
PAPER_SEALED_DEVICE = Device(gas=Gas(viscosity_law='sutherland',
                                     cavity='sealed'))

PHYSICS_PRESETS = MappingProxyType({
    'paper': PAPER_DEVICE,
    'paper_sutherland': PAPER_SUTHERLAND_DEVICE,
    'paper_sealed': PAPER_SEALED_DEVICE,
})

DEFAULT_PRESET = 'paper'


def physics_preset(name=DEFAULT_PRESET):
    """Return the named physics preset (a frozen ``Device``)."""
    try:
        return PHYSICS_PRESETS[name]
    except KeyError:
        raise ValueError(
            f'physics preset {name!r} is unknown: choose one of '
            f'{", ".join(sorted(PHYSICS_PRESETS))}') from None
