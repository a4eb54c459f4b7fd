"""
Frozen, validated parameters of a vibratory gyroscope device.

A device is geometry + material + gas + drive electronics. Every field carries
its SI unit in its name. Fields may be scalars or numpy arrays (one entry per
device), so the physics functions evaluate populations of devices at once.

Invalid values raise ``ValueError`` naming the class, the field, the value and
the allowed range, e.g.::

    Geometry.thickness_m = -2e-06 is out of range: allowed (0, 0.0001] m

The ranges are physical sanity limits for surface-micromachined gyroscopes,
not design rules.
"""

from dataclasses import dataclass, field, fields, replace

from gyro_emulator.validation import check_choice, check_range, check_temperature_c
import numpy as np

VISCOSITY_LAWS = ('constant', 'sutherland')
CAVITY_KINDS = ('vented', 'sealed')


def _validate(obj, spec):
    """Check each ``field: (low, high, unit[, low_open, high_open])`` of spec."""
    owner = type(obj).__name__
    for name, rng in spec.items():
        value = getattr(obj, name)
        checked = check_range(owner, name, value, *rng)
        if isinstance(checked, np.ndarray) and checked is not value:
            object.__setattr__(obj, name, checked)


@dataclass(frozen=True)
class Geometry:
    """
    Planar geometry of the proof mass, suspension and combs (Eq 5-12, 21).

    The proof mass is a square plate surrounded by ``frame_count`` square
    frames (inner and outer), each separated by ``clearance_m``. Four beams of
    type 1 and four of type 2 suspend it (Eq 6). Lengths in m, counts plain.
    """

    thickness_m: float = 2.0e-6
    plate_side_m: float = 855.5e-6
    clearance_m: float = 5.0e-6
    frame_width_m: float = 20.0e-6
    frame_count: int = 2
    hole_count: int = 2100
    hole_side_m: float = 5.0e-6
    beam1_width_m: float = 2.0e-6
    beam1_length_m: float = 54.9e-6
    beam2_width_m: float = 2.0e-6
    beam2_length_m: float = 54.9e-6
    substrate_gap_m: float = 2.0e-6
    flow_length_m: float = 2.0e-6
    comb_gap_m: float = 2.0e-6
    finger_width_m: float = 2.0e-6
    drive_capacitor_count: int = 400
    drive_finger_count: int = 200
    drive_finger_length_m: float = 30.0e-6
    drive_overlap_m: float = 19.75e-6
    sense_capacitor_count: int = 152
    sense_finger_count: int = 76
    sense_finger_length_m: float = 135.0e-6
    sense_overlap_m: float = 124.5e-6

    _SPEC = {
        'thickness_m': (0.0, 1e-4, 'm'),
        'plate_side_m': (0.0, 1e-2, 'm'),
        'clearance_m': (0.0, 1e-3, 'm', False),
        'frame_width_m': (0.0, 1e-3, 'm', False),
        'frame_count': (0, 10, '', False),
        'hole_count': (0, 1e6, '', False),
        'hole_side_m': (0.0, 1e-4, 'm', False),
        'beam1_width_m': (0.0, 1e-4, 'm'),
        'beam1_length_m': (0.0, 1e-2, 'm'),
        'beam2_width_m': (0.0, 1e-4, 'm'),
        'beam2_length_m': (0.0, 1e-2, 'm'),
        'substrate_gap_m': (0.0, 1e-3, 'm'),
        'flow_length_m': (0.0, 1e-3, 'm'),
        'comb_gap_m': (0.0, 1e-4, 'm'),
        'finger_width_m': (0.0, 1e-4, 'm'),
        'drive_capacitor_count': (0, 1e5, ''),
        'drive_finger_count': (0, 1e5, '', False),
        'drive_finger_length_m': (0.0, 1e-2, 'm', False),
        'drive_overlap_m': (0.0, 1e-2, 'm'),
        'sense_capacitor_count': (0, 1e5, ''),
        'sense_finger_count': (0, 1e5, '', False),
        'sense_finger_length_m': (0.0, 1e-2, 'm', False),
        'sense_overlap_m': (0.0, 1e-2, 'm'),
    }

    def __post_init__(self):
        """Validate every field; see the class docstring for units."""
        _validate(self, self._SPEC)
        holes = np.asarray(self.hole_count) * np.asarray(self.hole_side_m) ** 2
        if np.any(holes >= np.asarray(self.plate_side_m) ** 2):
            raise ValueError(
                'Geometry.hole_count = %r with hole_side_m = %r removes more '
                'than the whole plate: allowed hole area < plate_side_m^2'
                % (self.hole_count, self.hole_side_m))


@dataclass(frozen=True)
class Material:
    """
    Structural material: density and Young's modulus with Eq 22's law.

    ``E(T) = youngs_modulus_pa + youngs_temp_coeff_pa_k (T - youngs_ref_temp_c)``
    (Eq 22; the paper's polysilicon has -0.04 GPa/K).
    """

    density_kg_m3: float = 2330.0
    youngs_modulus_pa: float = 160.0e9
    youngs_ref_temp_c: float = 25.0
    youngs_temp_coeff_pa_k: float = -0.04e9

    _SPEC = {
        'density_kg_m3': (0.0, 3e4, 'kg/m^3'),
        'youngs_modulus_pa': (1e9, 1e12, 'Pa'),
        'youngs_ref_temp_c': (-100.0, 300.0, 'C', False),
        'youngs_temp_coeff_pa_k': (-1e9, 1e9, 'Pa/K', False),
    }

    def __post_init__(self):
        """Validate every field; see the class docstring for units."""
        _validate(self, self._SPEC)


@dataclass(frozen=True)
class Gas:
    """
    The gas in the device cavity (Eq 8-10).

    ``pressure_pa`` is the pressure at ``pressure_ref_temp_c``. A ``vented``
    cavity stays at that pressure at any temperature; a ``sealed`` one keeps
    its number density, so its pressure rises as T (ideal gas) and the mean
    free path stays constant. ``viscosity_law`` is ``constant`` (the paper's
    choice) or ``sutherland``: mu(T) = mu_ref (T/T_ref)^1.5 (T_ref + S)/(T + S).
    """

    molecule_diameter_m: float = 3.70e-10
    viscosity_pa_s: float = 1.85e-5
    viscosity_ref_temp_c: float = 25.0
    viscosity_law: str = 'constant'
    sutherland_constant_k: float = 110.4
    pressure_pa: float = 101325.0
    pressure_ref_temp_c: float = 25.0
    cavity: str = 'vented'
    relative_permittivity: float = 1.00059

    _SPEC = {
        'molecule_diameter_m': (1e-11, 1e-8, 'm'),
        'viscosity_pa_s': (0.0, 1e-2, 'Pa s'),
        'viscosity_ref_temp_c': (-100.0, 300.0, 'C', False),
        'sutherland_constant_k': (0.0, 1000.0, 'K', False),
        'pressure_pa': (0.0, 1e7, 'Pa'),
        'pressure_ref_temp_c': (-100.0, 300.0, 'C', False),
        'relative_permittivity': (1.0, 100.0, '', False),
    }

    def __post_init__(self):
        """Validate every field; see the class docstring for units."""
        _validate(self, self._SPEC)
        check_choice('Gas', 'viscosity_law', self.viscosity_law, VISCOSITY_LAWS)
        check_choice('Gas', 'cavity', self.cavity, CAVITY_KINDS)


@dataclass(frozen=True)
class DriveElectronics:
    """Comb-drive excitation (Eq 12): F_d = k_f N eps t V_dc V_ac / g_c."""

    dc_voltage_v: float = 27.0
    ac_voltage_v: float = 20.0
    comb_force_factor: float = 2.28

    _SPEC = {
        'dc_voltage_v': (0.0, 1000.0, 'V'),
        'ac_voltage_v': (0.0, 1000.0, 'V'),
        'comb_force_factor': (0.0, 100.0, ''),
    }

    def __post_init__(self):
        """Validate every field; see the class docstring for units."""
        _validate(self, self._SPEC)


@dataclass(frozen=True)
class Device:
    """
    A complete gyroscope: geometry, material, gas, drive and calibration.

    ``calibration_temp_c`` is where the user calibrates scale factor and bias
    (25 C in the paper), i.e. where the apparent rate equals the true rate.
    """

    geometry: Geometry = field(default_factory=Geometry)
    material: Material = field(default_factory=Material)
    gas: Gas = field(default_factory=Gas)
    drive: DriveElectronics = field(default_factory=DriveElectronics)
    calibration_temp_c: float = 25.0

    def __post_init__(self):
        """Check component types and the calibration temperature."""
        for name, kind in (('geometry', Geometry), ('material', Material),
                           ('gas', Gas), ('drive', DriveElectronics)):
            if not isinstance(getattr(self, name), kind):
                raise ValueError(
                    f'Device.{name} = {getattr(self, name)!r} is not allowed: '
                    f'expected a {kind.__name__}')
        check_temperature_c(self.calibration_temp_c, 'Device',
                            'calibration_temp_c')

    def with_gas(self, **changes):
        """Return a copy whose gas has ``changes`` applied (validated)."""
        return replace(self, gas=replace(self.gas, **changes))


def field_names(cls):
    """Return the public field names of a parameter dataclass."""
    return [f.name for f in fields(cls) if not f.name.startswith('_')]


def from_mapping(cls, mapping, owner=None):
    """
    Build ``cls`` from a mapping, rejecting unknown keys by name.

    Nested Device components are built recursively. Used by the YAML loaders.
    """
    owner = owner or cls.__name__
    if not isinstance(mapping, dict):
        raise ValueError(f'{owner} must be a mapping, got {mapping!r}')
    known = {f.name: f for f in fields(cls) if not f.name.startswith('_')}
    unknown = sorted(set(mapping) - set(known))
    if unknown:
        raise ValueError(
            f'{owner}: unknown field(s) {", ".join(unknown)}; allowed: '
            f'{", ".join(sorted(known))}')
    kwargs = {}
    nested = {'geometry': Geometry, 'material': Material, 'gas': Gas,
              'drive': DriveElectronics}
    for key, value in mapping.items():
        if cls is Device and key in nested:
            kwargs[key] = from_mapping(nested[key], value, f'{owner}.{key}')
        elif isinstance(value, bool) or (
                not isinstance(value, (int, float, str))):
            raise ValueError(
                f'{owner}.{key} = {value!r} is not a number or a name')
        else:
            kwargs[key] = value
    return cls(**kwargs)
