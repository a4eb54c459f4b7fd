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

from gyro_emulator.validation import (
    check_choice, check_range, check_temperature_c, MODEL_TEMP_RANGE_C, quote)
import numpy as np

VISCOSITY_LAWS = ('constant', 'sutherland')
YOUNGS_MODULUS_LAWS = ('paper', 'silicon')

#: Temperature coefficient of Young's modulus of single-crystal silicon near
#: room temperature, 1/K (about -60 ppm/K: Hopcroft, Nix and Kenny, J. MEMS
#: 19(2), 2010; the paper's polysilicon law, Eq 22, has -250 ppm/K).
SILICON_YOUNGS_TEMP_COEFF_PER_K = -60e-6
CAVITY_KINDS = ('vented', 'sealed')
#: Physical lower bounds of the sizes, closed: a zero or a denormal gives no device,
#: only an overflow (1/0, 1/5e-324) that would reach the output as NaN.
#: A structural film or beam is >= 100 nm thick or wide (surface micromachining).
MIN_FILM_M = 1e-7
#: A plate side or beam length is >= 1 um.
MIN_FEATURE_M = 1e-6
#: A gap, finger or overlap is >= 10 nm.
MIN_GAP_M = 1e-8
#: A cavity holds >= 1 mPa (a high vacuum; vacuum-packaged gyros hold 0.1-100 Pa).
MIN_PRESSURE_PA = 1e-3


def _ranged(default, low, high, unit, low_open=True):
    """
    Return a dataclass field with its default and allowed range.

    The range ``(low, high]`` (``[low, high]`` when ``low_open`` is False), in
    ``unit``, is kept in the field's metadata and checked by ``_validate``.
    """
    return field(default=default, metadata={'range': (low, high, unit, low_open)})


def _validate(obj):
    """Check every field of ``obj`` declared with ``_ranged`` against its range."""
    owner = type(obj).__name__
    for spec in fields(obj):
        if 'range' not in spec.metadata:
            continue
        value = getattr(obj, spec.name)
        checked = check_range(owner, spec.name, value, *spec.metadata['range'])
        if isinstance(checked, np.ndarray) and checked is not value:
            object.__setattr__(obj, spec.name, checked)


@dataclass(frozen=True)
class Geometry:
    """
    Planar geometry of the proof mass, suspension and combs (Eq 5-12, 21).

    The proof mass is a square plate surrounded by ``frame_count`` square
    frames (inner and outer), each separated by ``clearance_m``. Four beams of
    type 1 and four of type 2 suspend it (Eq 6). Lengths in m, counts plain.
    """

    thickness_m: float = _ranged(2.0e-6, MIN_FILM_M, 1e-4, 'm', low_open=False)
    plate_side_m: float = _ranged(855.5e-6, MIN_FEATURE_M, 1e-2, 'm', low_open=False)
    clearance_m: float = _ranged(5.0e-6, 0.0, 1e-3, 'm', low_open=False)
    frame_width_m: float = _ranged(20.0e-6, 0.0, 1e-3, 'm', low_open=False)
    frame_count: int = _ranged(2, 0, 10, '', low_open=False)
    hole_count: int = _ranged(2100, 0, 1e6, '', low_open=False)
    hole_side_m: float = _ranged(5.0e-6, 0.0, 1e-4, 'm', low_open=False)
    beam1_width_m: float = _ranged(2.0e-6, MIN_FILM_M, 1e-4, 'm', low_open=False)
    beam1_length_m: float = _ranged(54.9e-6, MIN_FEATURE_M, 1e-2, 'm', low_open=False)
    beam2_width_m: float = _ranged(2.0e-6, MIN_FILM_M, 1e-4, 'm', low_open=False)
    beam2_length_m: float = _ranged(54.9e-6, MIN_FEATURE_M, 1e-2, 'm', low_open=False)
    substrate_gap_m: float = _ranged(2.0e-6, MIN_GAP_M, 1e-3, 'm', low_open=False)
    flow_length_m: float = _ranged(2.0e-6, MIN_GAP_M, 1e-3, 'm', low_open=False)
    comb_gap_m: float = _ranged(2.0e-6, MIN_GAP_M, 1e-4, 'm', low_open=False)
    finger_width_m: float = _ranged(2.0e-6, MIN_GAP_M, 1e-4, 'm', low_open=False)
    drive_capacitor_count: int = _ranged(400, 1, 1e5, '', low_open=False)
    drive_finger_count: int = _ranged(200, 0, 1e5, '', low_open=False)
    drive_finger_length_m: float = _ranged(30.0e-6, 0.0, 1e-2, 'm', low_open=False)
    drive_overlap_m: float = _ranged(19.75e-6, MIN_GAP_M, 1e-2, 'm', low_open=False)
    sense_capacitor_count: int = _ranged(152, 1, 1e5, '', low_open=False)
    sense_finger_count: int = _ranged(76, 0, 1e5, '', low_open=False)
    sense_finger_length_m: float = _ranged(135.0e-6, 0.0, 1e-2, 'm', low_open=False)
    sense_overlap_m: float = _ranged(124.5e-6, MIN_GAP_M, 1e-2, 'm', low_open=False)

    def __post_init__(self):
        """Validate every field; see the class docstring for units."""
        _validate(self)
        holes = np.asarray(self.hole_count) * np.asarray(self.hole_side_m) ** 2
        if np.any(holes >= np.asarray(self.plate_side_m) ** 2):
            raise ValueError(
                'Geometry.hole_count = %r with hole_side_m = %r removes more '
                'than the whole plate: allowed hole area < plate_side_m^2'
                % (self.hole_count, self.hole_side_m))


@dataclass(frozen=True)
class Material:
    """
    Structural material: density and Young's modulus E(T).

    ``youngs_modulus_law`` ``paper`` (default) is Eq 22,
    ``E(T) = youngs_modulus_pa + youngs_temp_coeff_pa_k (T - youngs_ref_temp_c)``
    (the paper's polysilicon: -0.04 GPa/K of 160 GPa, -250 ppm/K);
    ``silicon`` is ``E(T) = youngs_modulus_pa (1 + a (T - youngs_ref_temp_c))``
    with a = :data:`SILICON_YOUNGS_TEMP_COEFF_PER_K` (-60 ppm/K, single-crystal
    silicon), and ``youngs_temp_coeff_pa_k`` is not used.
    """

    density_kg_m3: float = _ranged(2330.0, 100.0, 3e4, 'kg/m^3', low_open=False)
    youngs_modulus_pa: float = _ranged(160.0e9, 1e9, 1e12, 'Pa')
    youngs_ref_temp_c: float = _ranged(25.0, -100.0, 300.0, 'C', low_open=False)
    youngs_temp_coeff_pa_k: float = _ranged(-0.04e9, -1e9, 1e9, 'Pa/K', low_open=False)
    youngs_modulus_law: str = 'paper'

    def __post_init__(self):
        """Validate every field; see the class docstring for units."""
        _validate(self)
        check_choice('Material', 'youngs_modulus_law', self.youngs_modulus_law,
                     YOUNGS_MODULUS_LAWS)
        lowest = np.asarray(lowest_youngs_modulus_pa(self))
        if np.any(lowest < MIN_YOUNGS_MODULUS_PA):
            first = float(lowest[lowest < MIN_YOUNGS_MODULUS_PA].flat[0]) if lowest.ndim \
                else float(lowest)
            raise ValueError(
                f'Material.youngs_temp_coeff_pa_k = {quote(self.youngs_temp_coeff_pa_k)} takes '
                f'E(T) down to {first:.4g} Pa within the model temperatures '
                f'{list(MODEL_TEMP_RANGE_C)} C: allowed E(T) >= {MIN_YOUNGS_MODULUS_PA:g} Pa '
                'there')


#: Smallest Young's modulus at any model temperature, Pa (the field's own lower bound).
MIN_YOUNGS_MODULUS_PA = 1e9


def lowest_youngs_modulus_pa(material):
    """
    Return the least E(T) over :data:`~gyro_emulator.validation.MODEL_TEMP_RANGE_C`, Pa.

    E(T) is linear in T (either law), so its least value is at an end of the
    range; element-wise for arrays of parts.
    """
    ends = [np.asarray(t, dtype=float) - material.youngs_ref_temp_c for t in MODEL_TEMP_RANGE_C]
    if material.youngs_modulus_law == 'silicon':
        values = [material.youngs_modulus_pa * (1.0 + SILICON_YOUNGS_TEMP_COEFF_PER_K * d)
                  for d in ends]
    else:
        values = [material.youngs_modulus_pa + material.youngs_temp_coeff_pa_k * d
                  for d in ends]
    return np.minimum(*values)


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

    molecule_diameter_m: float = _ranged(3.70e-10, 1e-11, 1e-8, 'm')
    viscosity_pa_s: float = _ranged(1.85e-5, 1e-7, 1e-2, 'Pa s', low_open=False)
    viscosity_ref_temp_c: float = _ranged(25.0, -100.0, 300.0, 'C', low_open=False)
    viscosity_law: str = 'constant'
    sutherland_constant_k: float = _ranged(110.4, 0.0, 1000.0, 'K', low_open=False)
    pressure_pa: float = _ranged(101325.0, MIN_PRESSURE_PA, 1e7, 'Pa', low_open=False)
    pressure_ref_temp_c: float = _ranged(25.0, -100.0, 300.0, 'C', low_open=False)
    cavity: str = 'vented'
    relative_permittivity: float = _ranged(1.00059, 1.0, 100.0, '', low_open=False)

    def __post_init__(self):
        """Validate every field; see the class docstring for units."""
        _validate(self)
        check_choice('Gas', 'viscosity_law', self.viscosity_law, VISCOSITY_LAWS)
        check_choice('Gas', 'cavity', self.cavity, CAVITY_KINDS)


@dataclass(frozen=True)
class DriveElectronics:
    """Comb-drive excitation (Eq 12): F_d = k_f N eps t V_dc V_ac / g_c."""

    dc_voltage_v: float = _ranged(27.0, 1e-3, 1000.0, 'V', low_open=False)
    ac_voltage_v: float = _ranged(20.0, 1e-3, 1000.0, 'V', low_open=False)
    comb_force_factor: float = _ranged(2.28, 1e-3, 100.0, '', low_open=False)

    def __post_init__(self):
        """Validate every field; see the class docstring for units."""
        _validate(self)


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
                    f'Device.{name} = {quote(getattr(self, name))} is not allowed: '
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
        raise ValueError(f'{owner} must be a mapping, got {quote(mapping)}')
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
                f'{owner}.{key} = {quote(value)} is not a number or a name')
        else:
            kwargs[key] = value
    return cls(**kwargs)
