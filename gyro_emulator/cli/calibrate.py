"""
Calibrate from a measured log, export to the stacks users run, and check the emulated twin.

  calibrate noise LOG [--axis x|y|z|all] --format F -o OUT [--inflate F]
                  [--rostopic TOPIC] [--accel-scale S]
                  [--accel-noise-density A --accel-random-walk W]
      IEEE Std 952 noise identification of a static log (Allan deviation, the
      band-limited short taus left out, five terms with confidence intervals,
      read-offs) written for: kalibr (imu.yaml), openvins (kalibr_imu_chain.yaml),
      vins (IMU block), orbslam3 (IMU block), orbslam3-settings (a whole v1.0
      settings file), gazebo (gz-sensors <imu> block) or preset (this emulator's
      sensor YAML). The gyro and, when the log has one (accel_{x,y,z}_m_s2
      columns, an Imu's linear_acceleration), the accelerometer, with the same
      fit: the files are then complete from the log alone. Accelerometer figures
      given by hand replace the log's (the file says so); a gyro-only log without
      them leaves each file so that its consumer stops and names the field
      (docs/calibrate.md), never loads a wrong value (vins is refused).
  calibrate thermal LOG [LOG ...] --format px4|ardupilot|preset -o OUT
                    [--px4-gyro-id ID] [--px4-accel-id ID] [--accel-scale S]
      Bias against die temperature of a static log (temp_c and gyro columns;
      several one-axis files are x, y, z in order), written as PX4 TC_G0_*
      parameters, ArduPilot INS_TCAL1_GYR* parameters or this emulator's bias
      terms; with accelerometer columns too, PX4 TC_A0_*, ArduPilot
      INS_TCAL1_ACC* and the accelerometer's bias tempco.
      A log that spans too little temperature is refused: order k needs
      5 / 15 / 25 K (k = 1 / 2 / 3) and k + 3 distinct temperatures.
  calibrate check-noise LOG --config FITTED.yaml
      Simulate the fitted preset (as `simulate --config` does) at the log's rate
      and length for several seeds; compare the Allan deviation at every octave
      tau from 0.1 s to a tenth of the record (10 % tolerance).
  calibrate check-thermal LOG [LOG ...] --config FITTED.yaml [--px4 FILE]
      Simulate the fitted preset along the log's temperature and compare bias
      against temperature; with --px4, apply that correction to the log and
      report the spread before and after.

Every file states its source log, the tau range or temperature span used, the
continuous-to-discrete convention of its target and the inflation factor; its
first comment line says whether it is a whole file or a block to paste.
"""

from gyro_emulator.cli.allan import add_outlier_arguments
from gyro_emulator.cli.jsonout import add_overwrite

HELP = 'calibrate noise or thermal terms from a log; export to Kalibr, VINS, PX4, ...'

NOISE_FORMATS = ('kalibr', 'openvins', 'vins', 'orbslam3', 'orbslam3-settings', 'gazebo',
                 'preset')
THERMAL_FORMATS = ('px4', 'ardupilot', 'preset')


def _common_log(parser, many=False):
    if many:
        parser.add_argument('log', nargs='+', metavar='LOG',
                            help='thermal log: one CSV/bag, or one-axis CSVs for x, y, z')
        parser.add_argument('--gyro-scale', type=float, default=1.0, metavar='F',
                            help='multiply the logged rates by F first (a known scale error; '
                                 'default: %(default)s)')
        parser.add_argument('--temperature-topic', default=None,
                            help='sensor_msgs/Temperature topic of a bag '
                                 '(default: imu/temperature)')
    else:
        parser.add_argument('log', metavar='LOG', help='static log: CSV (.gz ok) or bag')
        parser.add_argument('--axis', choices=('x', 'y', 'z', 'all'), default='all',
                            help='axis to calibrate (default: every axis of the log)')
    parser.add_argument('--topic', default=None, help='Imu topic of a bag')
    parser.add_argument('--accel-scale', type=float, default=1.0, metavar='S',
                        help='multiply the logged accelerometer by S first (a log in g: '
                             '9.80665; default: %(default)s)')
    parser.add_argument('--json', metavar='OUT', help='write the results as JSON')
    parser.add_argument('--plot', metavar='PNG', help='write a plot')
    add_overwrite(parser)
    add_outlier_arguments(parser)


def add_arguments(parser):
    """Register ``calibrate noise|thermal|check-noise|check-thermal``."""
    sub = parser.add_subparsers(dest='what', metavar='WHAT')
    sub.required = True
    noise = sub.add_parser('noise', help='noise terms of a static log, exported')
    _common_log(noise)
    noise.add_argument('--format', required=True, choices=NOISE_FORMATS)
    noise.add_argument('-o', '--out', required=True, metavar='OUT', help='file to write')
    noise.add_argument('--inflate', type=float, default=1.0, metavar='F',
                       help='multiply N, B and K by F (stated in the file; default: none)')
    noise.add_argument('--rate-hz', type=float, default=None, metavar='R',
                       help="the estimator's IMU rate for discrete values (default: the log's)")
    noise.add_argument('--rostopic', default=None, metavar='TOPIC',
                       help="the IMU topic of Kalibr's rostopic and OpenVINS's (default: the "
                            "bag's Imu topic; /imu0 for a CSV log)")
    noise.add_argument('--accel-noise-density', type=float, default=None, metavar='A',
                       help='accelerometer white-noise density in m/s^2/sqrt(Hz), continuous '
                            "(Kalibr's accelerometer_noise_density): replaces the log's (a "
                            'gyro-only log does not give it); with --accel-random-walk')
    noise.add_argument('--accel-random-walk', type=float, default=None, metavar='W',
                       help='accelerometer bias random walk in m/s^3/sqrt(Hz), continuous '
                            "(Kalibr's accelerometer_random_walk); with --accel-noise-density")
    therm = sub.add_parser('thermal', help='bias against temperature, exported')
    _common_log(therm, many=True)
    therm.add_argument('--format', required=True, choices=THERMAL_FORMATS)
    therm.add_argument('-o', '--out', required=True, metavar='OUT', help='file to write')
    therm.add_argument('--order', type=int, default=3, choices=(1, 2, 3),
                       help='highest polynomial order wanted (default: %(default)s)')
    therm.add_argument('--window-s', type=float, default=60.0, metavar='S',
                       help='group length of a log without gaps (default: %(default)s)')
    therm.add_argument('--px4-gyro-id', type=int, default=None, metavar='ID',
                       help="px4: the gyro's device id (param show CAL_GYRO0_ID), written as "
                            'TC_G0_ID; PX4 corrects no gyro until TC_G0_ID is set')
    therm.add_argument('--px4-accel-id', type=int, default=None, metavar='ID',
                       help="px4: the accelerometer's device id (param show CAL_ACC0_ID), "
                            'written as TC_A0_ID; PX4 corrects no accelerometer until it is set')
    check = sub.add_parser('check-noise', help='simulate the fitted preset; compare ADEV')
    _common_log(check)
    check.add_argument('--config', required=True, metavar='YAML', help='the fitted preset')
    check.add_argument('--seeds', type=int, default=8, metavar='N',
                       help='simulated records averaged (default: %(default)s)')
    tcheck = sub.add_parser('check-thermal', help='simulate the fitted preset; compare bias(T)')
    _common_log(tcheck, many=True)
    tcheck.add_argument('--config', required=True, metavar='YAML', help='the fitted preset')
    tcheck.add_argument('--px4', metavar='PARAMS', help='a PX4 file to apply to the log')
    tcheck.add_argument('--window-s', type=float, default=60.0, metavar='S',
                        help='group length of a log without gaps (default: %(default)s)')


def run(args):
    """Run the chosen calibration."""
    # The calibration modules load scipy and statsmodels (1-4 s): imported
    # here, since `gyro-emulator --help` imports every command module.
    from gyro_emulator.cli.calibrate_commands import RUNS

    return RUNS[args.what](args)
