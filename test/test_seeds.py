"""Default seeds from the node name (sensor.streams.seed_from_name)."""

from gyro_emulator.sensor import streams
from gyro_emulator.sensor.config import load_sensor_config, SensorConfig
from gyro_emulator.sensor.model import GyroModel
import numpy as np
import pytest


def test_a_name_gives_the_same_seed_every_time_and_names_differ():
    names = [f'/robot/imu{i}/gyro_emulator' for i in range(200)] + ['/gyro_emulator', '/a']
    seeds = [streams.seed_from_name(n) for n in names]
    assert seeds == [streams.seed_from_name(n) for n in names]
    assert len(set(seeds)) == len(names)
    assert all(0 <= s <= streams.NAME_SEED_MAX for s in seeds)


def test_seeds_of_similar_names_are_unrelated():
    """The top bit of the seeds of 2000 neighbouring names is a fair coin (not all equal)."""
    seeds = np.array([streams.seed_from_name(f'/imu{i}') for i in range(2000)], dtype=np.uint64)
    ones = int(np.sum((seeds >> np.uint64(62)) & np.uint64(1)))
    # Binomial(2000, 0.5): sd 22; 5 sd either way.
    assert abs(ones - 1000) < 112, ones


def test_the_seed_of_a_name_reproduces_the_model_exactly():
    config = SensorConfig(electronics_noise_rad_s_sqrt_hz=1e-3)
    seed = streams.seed_from_name('/left/gyro_emulator')
    runs = [GyroModel(config, 100.0, np.random.default_rng(seed)).run(np.zeros((50, 3)), 25.0)
            for _ in range(2)]
    assert np.array_equal(runs[0].gyro_rad_s, runs[1].gyro_rad_s)


@pytest.mark.parametrize('name', ['', None, 3])
def test_a_bad_name_is_refused(name):
    with pytest.raises(ValueError, match='a non-empty string'):
        streams.seed_from_name(name)


def test_the_correlation_bound_of_the_redundant_imu_test_rarely_fails_by_chance():
    """
    Calibrate ``|r| < 0.3`` of test_node_sim on 200 pairs of name-seeded parts.

    The statistic is the correlation of the first differences of two resting
    consumer gyros (42 Hz filter) over 400 samples at 250 Hz, as in the ROS
    test. Independent parts: r centred on 0, and |r| above 0.3 in none of
    200 pairs (a false alarm rate well below 1 %).
    """
    rs = []
    config = load_sensor_config('consumer')
    for k in range(200):
        pair = []
        for side in 'ab':
            seed = streams.seed_from_name(f'/pair{k}/{side}/gyro_emulator')
            model = GyroModel(config, 250.0, np.random.default_rng(seed))
            pair.append(np.diff(model.run(np.zeros((400, 3)), 25.0).gyro_rad_s[:, 2]))
        rs.append(np.corrcoef(*pair)[0, 1])
    r = np.array(rs)
    assert abs(r.mean()) < 3 * r.std() / np.sqrt(len(r))
    assert np.max(np.abs(r)) < 0.3, np.max(np.abs(r))
