"""The topic table: one definition per topic, valid types, clear lookups."""

from gyro_emulator.recording import cdr, topics
from gyro_emulator.recording.bag import message_definition
import pytest


def test_names_are_unique_and_every_type_has_a_definition():
    names = [t.name for t in topics.NODE_TOPICS]
    assert len(names) == len(set(names))
    for topic in topics.NODE_TOPICS:
        assert message_definition(topic.type_name), topic.type_name


def test_recorded_and_rate_inputs_come_from_the_table():
    assert set(topics.RECORDED_BY_DEFAULT) <= set(topics.NODE_TOPICS)
    assert set(topics.RATE_INPUTS.values()) <= set(topics.NODE_TOPICS)
    assert set(topics.TRUTH_TOPICS.values()) <= set(topics.NODE_TOPICS)


def test_fixed_layout_topics_decode_with_cdr():
    """Every high-rate topic of the table has a fixed CDR layout for fast reading."""
    for topic in (topics.RATE_CMD, topics.TEMPERATURE_CMD, topics.ACCEL_CMD,
                  topics.IMU_OUT, topics.DIE_TEMPERATURE_OUT, topics.TRUTH_RATE):
        assert cdr.layout_of(topic.type_name) is not None


@pytest.mark.parametrize('name', ['imu/data_raw', '/imu/data_raw'])
def test_lookup_by_name_with_or_without_slash(name):
    assert topics.by_name(name) is topics.IMU_OUT
    assert topics.IMU_OUT.bag_name == '/imu/data_raw'


def test_unknown_name_and_bad_fields_are_one_line_errors():
    with pytest.raises(ValueError, match="'cmd/nope' is not in the topic table"):
        topics.by_name('cmd/nope')
    with pytest.raises(ValueError, match="Topic.qos = 'fast' is not allowed"):
        topics.Topic('x', topics.IMU, 'fast', 'out', '')
    with pytest.raises(ValueError, match="Topic.direction = 'up' is not allowed"):
        topics.Topic('x', topics.IMU, 'reliable', 'up', '')
