"""ROS bags and MCAP files as logs (attend.io.bags): bags of each format written with rosbags'
writers, read back and compared with the values written (exactly, or to the resampling rule's
closed form); `attend estimate` on a bag equals it on the equivalent CSV; each bad input is a one-line
error naming the file and the topic, field or key."""

from __future__ import annotations

import sys

import numpy as np
import pytest

from attend import io
from attend._validation import AttendInputError
from attend.cli import main
from attend.models.linear import LinearSystem, simulate

rosbags = pytest.importorskip("rosbags")
from rosbags.rosbag1 import Writer as Writer1  # noqa: E402
from rosbags.rosbag2 import Writer as Writer2  # noqa: E402
from rosbags.rosbag2.enums import StoragePlugin  # noqa: E402
from rosbags.typesys import Stores, get_typestore  # noqa: E402

START = 1_700_000_000 * 10**9  # bag time of the first message [ns]
STEP = 15_625_000  # 1/64 s in ns: exact in binary, so the grid's seconds equal a CSV's k / 64
FORMATS = ["ros1", "ros2", "db3", "mcap", "mcap-folder"]


class Bag:
    """Messages for one bag, written in any of the FORMATS with rosbags' own writers."""

    def __init__(self, kind: str = "ros2"):
        self.kind = kind
        self.ros1 = kind == "ros1"
        self.store = get_typestore(Stores.ROS1_NOETIC if self.ros1 else Stores.ROS2_HUMBLE)
        self.messages = []  # (topic, msgtype, receive [ns], message)

    def _header(self, stamp: int):
        types = self.store.types
        time = types["builtin_interfaces/msg/Time"](sec=stamp // 10**9, nanosec=stamp % 10**9)
        return types["std_msgs/msg/Header"](stamp=time, frame_id="base", **({"seq": 0} if self.ros1 else {}))

    def imu(self, topic, received, gyro, stamp=None, covariance=0.0):
        types = self.store.types
        vector, quaternion = types["geometry_msgs/msg/Vector3"], types["geometry_msgs/msg/Quaternion"]
        message = types["sensor_msgs/msg/Imu"](
            header=self._header(received if stamp is None else stamp), orientation=quaternion(x=0.0, y=0.0, z=0.0, w=1.0),
            orientation_covariance=np.full(9, covariance), angular_velocity=vector(x=gyro[0], y=gyro[1], z=gyro[2]),
            angular_velocity_covariance=np.zeros(9), linear_acceleration=vector(x=0.0, y=0.0, z=9.81),
            linear_acceleration_covariance=np.zeros(9))
        self.messages.append((topic, "sensor_msgs/msg/Imu", received, message))

    def float64(self, topic, received, value):
        self.messages.append((topic, "std_msgs/msg/Float64", received, self.store.types["std_msgs/msg/Float64"](data=value)))

    def pose(self, topic, received, xyz):
        types = self.store.types
        pose = types["geometry_msgs/msg/Pose"](position=types["geometry_msgs/msg/Point"](x=xyz[0], y=xyz[1], z=xyz[2]),
                                               orientation=types["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0))
        self.messages.append((topic, "geometry_msgs/msg/PoseStamped", received,
                              types["geometry_msgs/msg/PoseStamped"](header=self._header(received), pose=pose)))

    def text(self, topic, received, value):
        self.messages.append((topic, "std_msgs/msg/String", received, self.store.types["std_msgs/msg/String"](data=value)))

    def array(self, topic, received, values):
        types = self.store.types
        layout = types["std_msgs/msg/MultiArrayLayout"](dim=[], data_offset=0)
        self.messages.append((topic, "std_msgs/msg/Float64MultiArray", received,
                              types["std_msgs/msg/Float64MultiArray"](layout=layout, data=np.array(values, dtype=float))))

    def write(self, folder, name="flight", empty_topics=()):
        """Write the bag under folder; returns the path to read (a file or a ROS 2 bag folder)."""
        topics = {topic: msgtype for topic, msgtype, _, _ in self.messages}
        topics.update({topic: "std_msgs/msg/Float64" for topic in empty_topics})
        if self.ros1:
            path = folder / f"{name}.bag"
            writer = Writer1(path)
        else:
            path = folder / name
            plugin = StoragePlugin.MCAP if self.kind.startswith("mcap") else StoragePlugin.SQLITE3
            writer = Writer2(path, version=8, storage_plugin=plugin)
        with writer:
            connections = {topic: writer.add_connection(topic, msgtype, typestore=self.store)
                           for topic, msgtype in topics.items()}
            for topic, msgtype, received, message in sorted(self.messages, key=lambda m: m[2]):
                data = (self.store.serialize_ros1 if self.ros1 else self.store.serialize_cdr)(message, msgtype)
                writer.write(connections[topic], received, data)
        if self.kind == "db3":
            return path / f"{name}.db3"
        if self.kind == "mcap":
            return path / f"{name}.mcap"
        return path


def _model(columns: str, log: str = "", outputs=("gyro_x",), inputs="") -> str:
    """A linear model file with one output per name in outputs, reading the bag as [log.columns] says."""
    n = len(outputs)
    return f"""
[model]
A = {np.diag(-np.ones(n)).tolist()}
B = {[[1.0]] * n if inputs else [[0.0]] * n}
C = {np.eye(n).tolist()}

[outputs]
columns = {list(outputs)!r}

[[inputs]]
name = "u"
{'column = "' + inputs + '"' if inputs else 'prior_precision = 1.0'}

[observer]
kernel_width = 0.05
sensor_precision = 1e4
process_precision = 1e2

[log]
{log}

[log.columns]
{columns}
""".replace("'", '"')


def _folder(tmp_path, name):
    """A fresh subfolder (a second bag in the same test)."""
    (tmp_path / name).mkdir()
    return tmp_path / name


def _read(tmp_path, bag: Bag, columns: str, log: str = "", outputs=("gyro_x",), inputs="", gaps=False, **write):
    path = bag.write(tmp_path, **write)
    (tmp_path / "model.toml").write_text(_model(columns, log, outputs, inputs))
    return io.read_log(path, io.read_model(tmp_path / "model.toml"), gaps=gaps)


IMU_COLUMNS = """gyro_x = { topic = "/imu", field = "angular_velocity.x" }
gyro_y = { topic = "/imu", field = "angular_velocity.y" }
motor = { topic = "/motor", field = "data" }"""


@pytest.mark.parametrize("kind", FORMATS)
def test_each_format_reads_back_the_values_written(tmp_path, kind):
    bag = Bag(kind)
    rng = np.random.default_rng(0)
    gyro, motor = rng.normal(size=(40, 2)), rng.normal(size=40)
    for k in range(40):
        bag.imu("/imu", START + k * STEP, (gyro[k, 0], gyro[k, 1], 0.0))
        bag.float64("/motor", START + k * STEP, motor[k])
    log = _read(tmp_path, bag, IMU_COLUMNS, outputs=("gyro_x", "gyro_y"), inputs="motor")
    assert np.array_equal(log.time, np.arange(40) / 64) and log.uniform and log.dt == 1 / 64
    assert np.array_equal(log.columns["gyro_x"], gyro[:, 0]) and np.array_equal(log.columns["gyro_y"], gyro[:, 1])
    assert np.array_equal(log.columns["motor"], motor) and np.array_equal(log.columns["t"], log.time)
    assert "stamps: /imu header, /motor receive" in log.origin and "linear interpolation" in log.origin
    assert log.labels[2] == "sample 3 (t = 0.03125 s)"


@pytest.mark.parametrize("rule", ["linear", "hold"])
def test_slower_topic_resampled_to_the_rules_closed_form(tmp_path, rule):
    bag = Bag()
    fast = START + np.arange(100) * STEP
    slow = START + 3_000_000 + np.arange(30) * (3 * STEP + 1_000_001)  # ~21 Hz, off the fast grid, uneven ns
    slow_values = np.cos(np.arange(30))
    for k, stamp in enumerate(fast):
        bag.imu("/imu", int(stamp), (np.sin(k), 0.0, 0.0))
    for k, stamp in enumerate(slow):
        bag.float64("/motor", int(stamp), slow_values[k])
    log = _read(tmp_path, bag, IMU_COLUMNS, f'resample = "{rule}"', outputs=("gyro_x", "gyro_y"), inputs="motor")
    # span: the first fast message at or after the slow topic's first, up to the slow topic's last
    first = int(np.argmax(fast >= slow[0]))
    grid = fast[first:][fast[first:] <= slow[-1]]
    assert np.array_equal(log.time, (grid - grid[0]) / 1e9)
    assert np.array_equal(log.columns["gyro_x"], np.sin(np.arange(first, first + len(grid))))  # the grid topic: exact
    j = np.searchsorted(slow, grid, side="right") - 1
    if rule == "hold":
        expected = slow_values[j]
    else:
        weight = (grid - slow[j]) / (slow[j + 1] - slow[j])
        expected = slow_values[j] + weight * (slow_values[j + 1] - slow_values[j])
    assert np.array_equal(log.columns["motor"], expected)


def test_rate_and_grid_topic_and_linear_ramp(tmp_path):
    """A 32 Hz grid on the 64 Hz topic; a ramp on a 20 Hz topic interpolates to the ramp itself."""
    bag = Bag()
    for k in range(64):
        bag.imu("/imu", START + k * STEP, (float(k), 0.0, 0.0))
    ramp = START + 1_000_000 + np.arange(21) * 50_000_000
    for stamp in ramp:
        bag.float64("/motor", int(stamp), 2.0 + 3.0 * (stamp - START) / 1e9)
    log = _read(tmp_path, bag, IMU_COLUMNS, 'rate_hz = 32\ngrid_topic = "/imu"', outputs=("gyro_x", "gyro_y"),
                inputs="motor")
    assert log.dt == pytest.approx(1 / 32, rel=1e-12) and log.uniform
    assert np.array_equal(log.columns["gyro_x"], 1.0 + 2.0 * np.arange(len(log.time)))  # from the 2nd IMU message
    assert np.allclose(log.columns["motor"], 2.0 + 3.0 * (log.time + STEP / 1e9), rtol=0, atol=1e-12)


def test_field_paths_arrays_and_nested_messages(tmp_path):
    bag = Bag()
    for k in range(10):
        bag.imu("/imu", START + k * STEP, (0.0, 0.0, 0.0), covariance=0.5 * k)
        bag.pose("/pose", START + k * STEP, (k, 2.0 * k, 3.0 * k))
        bag.array("/motors", START + k * STEP, [k, -k, 10.0 * k])
    columns = """cov = { topic = "/imu", field = "orientation_covariance[4]" }
z = { topic = "/pose", field = "pose.position.z" }
m3 = { topic = "/motors", field = "data[2]" }"""
    log = _read(tmp_path, bag, columns, outputs=("cov", "z"), inputs="m3")
    k = np.arange(10)
    assert np.array_equal(log.columns["cov"], 0.5 * k) and np.array_equal(log.columns["z"], 3.0 * k)
    assert np.array_equal(log.columns["m3"], 10.0 * k)


def test_header_or_receive_stamps(tmp_path):
    """Header stamps 5 ms after the receive time: "auto" uses them, "receive" does not."""
    def bag():
        made = Bag()
        for k in range(20):
            made.imu("/imu", START + k * STEP, (float(k), 0.0, 0.0), stamp=START + k * STEP + 5_000_000)
            made.float64("/motor", START + k * STEP, float(k))
        return made

    header = _read(_folder(tmp_path, "a"), bag(), IMU_COLUMNS,
                   outputs=("gyro_x", "gyro_y"), inputs="motor")
    received = _read(_folder(tmp_path, "b"), bag(), IMU_COLUMNS,
                     'stamps = "receive"', outputs=("gyro_x", "gyro_y"), inputs="motor")
    assert np.array_equal(received.columns["gyro_x"], received.columns["motor"])  # same stamps: same values
    # header: the IMU is 5 ms late, the motor column is interpolated 5 ms after each motor message
    assert np.array_equal(header.columns["gyro_x"], np.arange(len(header.time)))
    assert np.allclose(header.columns["motor"], np.arange(len(header.time)) + 5 / 15.625, atol=1e-12)
    assert "/imu header" in header.origin and "/imu receive" in received.origin


def test_dropouts_are_missing_with_gaps_and_refused_without(tmp_path):
    bag = Bag()
    for k in [*range(20), *range(30, 50)]:  # the IMU drops 10 messages
        bag.imu("/imu", START + k * STEP, (float(k), 0.0, 0.0))
    for k in range(50):
        bag.float64("/motor", START + k * STEP, float(k))
    log = _read(tmp_path, bag, IMU_COLUMNS, 'grid_topic = "/motor"', outputs=("gyro_x", "gyro_y"), inputs="motor",
                gaps=True)
    missing = np.isnan(log.columns["gyro_x"])
    assert np.array_equal(np.flatnonzero(missing), np.arange(20, 30)) and not np.isnan(log.columns["motor"]).any()
    assert "dropouts: gyro_x: 10 missing, gyro_y: 10 missing" in log.origin
    with pytest.raises(AttendInputError, match=r"flight: topic '/imu', field 'angular_velocity.x' \(column 'gyro_x'\): "
                                               r"no message for 0.171875 s .* 10 grid samples"):
        io.read_log(tmp_path / "flight", io.read_model(tmp_path / "model.toml"))


def test_nan_fields_are_missing_messages(tmp_path):
    bag = Bag()
    for k in range(20):
        bag.imu("/imu", START + k * STEP, (np.nan if k == 7 else float(k), 0.0, 0.0))
        bag.float64("/motor", START + k * STEP, float(k))
    log = _read(tmp_path, bag, IMU_COLUMNS, outputs=("gyro_x", "gyro_y"), inputs="motor")
    assert np.array_equal(log.columns["gyro_x"], np.arange(20.0))  # interpolated across the one NaN


def _linear_case(tmp_path):
    """A simulated 2-state log at 64 Hz as a CSV and as a ROS 2 bag (the same numbers)."""
    system = LinearSystem([[0.0, 1.0], [-4.0, -0.8]], [[0.0], [1.0]], [[1.0, 0.0]])
    n = 160
    u = np.sin(np.arange(n) / 10)[:, None]
    simulated = simulate(system, u, 1 / 64, kernel_width=0.05, process_std=0.05, measurement_std=0.01, seed=3)
    y, u = simulated.outputs[:, 0].tolist(), u[:, 0].tolist()  # Python floats: repr round-trips them exactly
    model = f"""
[model]
A = {system.A.tolist()}
B = {system.B.tolist()}
C = {system.C.tolist()}
[outputs]
columns = ["y"]
[[inputs]]
name = "force"
column = "u"
[observer]
kernel_width = 0.05
sensor_precision = 1e4
process_precision = 400.0
[log.columns]
y = {{ topic = "/position", field = "pose.position.x" }}
u = {{ topic = "/force", field = "data" }}
"""
    (tmp_path / "model.toml").write_text(model)
    rows = [f"{k / 64!r},{y[k]!r},{u[k]!r}" for k in range(n)]
    (tmp_path / "log.csv").write_text("t,y,u\n" + "\n".join(rows) + "\n")
    bag = Bag()
    for k in range(n):
        bag.pose("/position", START + k * STEP, (y[k], 0.0, 0.0))
        bag.float64("/force", START + k * STEP + 2_000_000, u[k])  # received 2 ms later: still the grid's sample
    return tmp_path / "model.toml", tmp_path / "log.csv", bag


def test_estimate_on_a_bag_equals_the_csv(tmp_path, capsys):
    model, csv, bag = _linear_case(tmp_path)
    bag.messages = [(t, m, r - 2_000_000 if t == "/force" else r, msg) for t, m, r, msg in bag.messages]
    path = bag.write(tmp_path)
    assert main(["estimate", str(model), str(csv), "--out", str(tmp_path / "csv.csv"), "--no-progress"]) == 0
    assert main(["estimate", str(model), str(path), "--out", str(tmp_path / "bag.csv"), "--no-progress"]) == 0
    assert "ROS 2 bag: 160 samples every 0.015625 s" in capsys.readouterr().out
    assert (tmp_path / "bag.csv").read_bytes() == (tmp_path / "csv.csv").read_bytes()  # bit for bit


@pytest.mark.parametrize("kind", ["ros1", "mcap"])
def test_estimate_on_other_formats_and_hold(tmp_path, kind):
    model, csv, ros2 = _linear_case(tmp_path)
    bag = Bag(kind)
    for topic, _, received, message in ros2.messages:
        if topic == "/position":
            bag.pose(topic, received, (message.pose.position.x, 0.0, 0.0))
        else:
            bag.float64(topic, received, message.data)
    path = bag.write(tmp_path)
    model.write_text(model.read_text().replace("[log.columns]", '[log]\nresample = "hold"\n[log.columns]'))
    assert main(["estimate", str(model), str(csv), "--out", str(tmp_path / "csv.csv"), "--no-progress"]) == 0
    assert main(["estimate", str(model), str(path), "--out", str(tmp_path / "bag.csv"), "--no-progress"]) == 0
    # the force is received 2 ms after each position: the span starts at the 2nd position, and "hold" gives
    # each grid time the force of the step before (one step late)
    from_csv = np.loadtxt(tmp_path / "csv.csv", delimiter=",", skiprows=1)
    from_bag = np.loadtxt(tmp_path / "bag.csv", delimiter=",", skiprows=1)
    assert from_bag.shape == (159, from_csv.shape[1])
    assert np.array_equal(from_bag[:, 0], from_csv[:-1, 0])
    assert np.abs(from_bag[:, 1] - from_csv[1:, 1]).max() < 0.05


def test_identify_reads_a_bag(tmp_path, capsys):
    model, csv, bag = _linear_case(tmp_path)
    path = bag.write(tmp_path)
    model.write_text(model.read_text().replace("[log.columns]", '[learning]\nfree = ["A[2,1]"]\nmax_iterations = 3\n'
                                                                 "[log.columns]"))
    code = main(["identify", str(model), str(path), "--out", str(tmp_path / "learned.toml"), "--no-progress",
                 "--allow-unconverged"])
    assert code in (0, 3) and "free energy" in capsys.readouterr().out


def test_csv_model_files_and_logs_unchanged(tmp_path):
    """A model file without [log.columns] has no layout; with one, a CSV log still reads as a CSV."""
    model, csv, _ = _linear_case(tmp_path)
    with_layout = io.read_model(model)
    assert with_layout.bag_layout.topics == ("/position", "/force") and with_layout.bag_layout.resample == "linear"
    text = model.read_text()
    model.write_text(text[:text.index("[log.columns]")])
    plain = io.read_model(model)
    assert plain.bag_layout is None
    assert np.array_equal(io.read_log(csv, with_layout).columns["y"], io.read_log(csv, plain.time_column).columns["y"])


# --- bad input: one line naming the file and the topic, field or key --------------------------------------------


def _bad(tmp_path, bag, columns=IMU_COLUMNS, log="", gaps=False, **write):
    with pytest.raises(AttendInputError) as error:
        _read(tmp_path, bag, columns, log, outputs=("gyro_x", "gyro_y"), inputs="motor", gaps=gaps, **write)
    message = str(error.value)
    assert "\n" not in message and str(tmp_path) in message
    return message


def _imu_and_motor(n=20, kind="ros2"):
    bag = Bag(kind)
    for k in range(n):
        bag.imu("/imu", START + k * STEP, (float(k), 0.0, 0.0))
        bag.float64("/motor", START + k * STEP, float(k))
    return bag


def test_missing_topic(tmp_path):
    message = _bad(tmp_path, _imu_and_motor(), IMU_COLUMNS.replace('"/motor"', '"/motors"'))
    assert "no topic '/motors' (column motor of [log.columns]); the bag has /imu (sensor_msgs/msg/Imu), /motor " \
           "(std_msgs/msg/Float64)" in message


def test_field_not_in_the_message_type(tmp_path):
    message = _bad(tmp_path, _imu_and_motor(), IMU_COLUMNS.replace("angular_velocity.y", "angular_velocity.w"))
    assert "topic '/imu' (sensor_msgs/msg/Imu), field 'angular_velocity.w' (column 'gyro_y'): " \
           "geometry_msgs/msg/Vector3 has no field 'w'; it has x, y, z" in message
    message = _bad(_folder(tmp_path, "b"), _imu_and_motor(),
                   IMU_COLUMNS.replace("angular_velocity.y", "angular_rate.y"))
    assert "sensor_msgs/msg/Imu has no field 'angular_rate'; it has header, orientation" in message


@pytest.mark.parametrize("field, expected", [
    ("angular_velocity", "'angular_velocity' is a geometry_msgs/msg/Vector3 message, not a number; name one of its "
                         "fields: angular_velocity.x, angular_velocity.y, angular_velocity.z"),
    ("orientation_covariance", "'orientation_covariance' is an array of 9 float64; name one element, e.g. "
                               "\"orientation_covariance[0]\""),
    ("orientation_covariance[9]", "'orientation_covariance' has 9 elements (indices 0..8), got index 9"),
    ("header.frame_id", "a string, not a number"),
    ("angular_velocity.x.y", "'angular_velocity.x' is a float64, it has no field 'y'"),
    ("angular_velocity[0].x", "'angular_velocity' is not an array; remove [0]"),
])
def test_non_numeric_fields(tmp_path, field, expected):
    message = _bad(tmp_path, _imu_and_motor(), IMU_COLUMNS.replace("angular_velocity.y", field))
    assert f"field {field!r} (column 'gyro_y'): " in message and expected in message


def test_string_topic_and_short_sequence(tmp_path):
    bag = _imu_and_motor()
    bag.messages = [m for m in bag.messages if m[0] != "/motor"]
    for k in range(20):
        bag.array("/motor", START + k * STEP, [1.0] if k == 4 else [1.0, 2.0])
    message = _bad(tmp_path, bag, IMU_COLUMNS.replace('field = "data"', 'field = "data[1]"'))
    assert "topic '/motor', message 5: field 'data[1]' (column 'motor'): 'data' has 1 elements, index 1" in message


def test_empty_topic_and_one_message(tmp_path):
    bag = _imu_and_motor()
    bag.messages = [m for m in bag.messages if m[0] != "/motor"]
    message = _bad(tmp_path, bag, empty_topics=("/motor",))
    assert "topic '/motor' (column motor) has no messages; expected at least 2" in message
    bag.float64("/motor", START, 1.0)
    message = _bad(_folder(tmp_path, "b"), bag)
    assert "topic '/motor' (column motor) has 1 message" in message


@pytest.mark.parametrize("kind", ["ros2", "ros1"])
def test_stamps_going_backwards_or_repeating(tmp_path, kind):
    bag = Bag(kind)
    for k in range(20):
        stamp = START + (k - 2 if k == 10 else k) * STEP
        bag.imu("/imu", START + k * STEP, (float(k), 0.0, 0.0), stamp=stamp)
        bag.float64("/motor", START + k * STEP, float(k))
    message = _bad(tmp_path, bag)
    assert "topic '/imu': the header stamp of message 11 (t = 0.125 s into the bag) goes backwards (message 10: " \
           "t = 0.140625 s into the bag)" in message and 'stamps = "receive"' in message
    bag = Bag(kind)
    for k in range(20):
        bag.imu("/imu", START + k * STEP, (float(k), 0.0, 0.0), stamp=START)  # an unset header stamp: all equal
        bag.float64("/motor", START + k * STEP, float(k))
    message = _bad(_folder(tmp_path, "b"), bag)
    assert "the header stamp of message 2 (t = 0 s into the bag) repeats the previous one" in message


def test_grid_faster_than_the_topics(tmp_path):
    message = _bad(tmp_path, _imu_and_motor(), log="rate_hz = 200")
    assert "a grid every 0.005 s (200 Hz, [log] rate_hz or dt, or [model] dt) is faster than every topic named in [log.columns]: " \
           "the fastest, '/imu', has a message every 0.015625 s (64 Hz)" in message and "rate_hz <= 64" in message


def test_topics_without_a_common_span(tmp_path):
    bag = Bag()
    for k in range(10):
        bag.imu("/imu", START + k * STEP, (float(k), 0.0, 0.0))
        bag.float64("/motor", START + (20 + k) * STEP, float(k))
    message = _bad(tmp_path, bag)
    assert "the topics have no common span of 2 grid samples" in message and \
           "motor (/motor): t = 0.3125 s into the bag to 0.453125 s" in message


def test_infinite_value(tmp_path):
    bag = _imu_and_motor()
    bag.messages = [(t, m, r, bag.store.types["std_msgs/msg/Float64"](data=np.inf) if t == "/motor" and r == START + 3 * STEP
                     else msg) for t, m, r, msg in bag.messages]
    message = _bad(tmp_path, bag)
    assert "topic '/motor', message 4 (t = 0.046875 s into the bag), field 'data' (column 'motor'): expected a " \
           "finite number, got inf" in message


def test_header_stamps_required_but_absent(tmp_path):
    message = _bad(tmp_path, _imu_and_motor(), log='stamps = "header"')
    assert "topic '/motor': its messages (std_msgs/msg/Float64) have no header" in message


def test_without_rosbags(tmp_path, monkeypatch):
    path = _imu_and_motor().write(tmp_path)
    (tmp_path / "model.toml").write_text(_model(IMU_COLUMNS, outputs=("gyro_x", "gyro_y"), inputs="motor"))
    model = io.read_model(tmp_path / "model.toml")
    for name in [name for name in sys.modules if name == "rosbags" or name.startswith("rosbags.")]:
        monkeypatch.setitem(sys.modules, name, None)
    monkeypatch.setitem(sys.modules, "rosbags", None)
    with pytest.raises(AttendInputError, match=r"flight: reading a ROS bag needs the rosbags package: "
                                               r'pip install "attend\[ros\]"$'):
        io.read_log(path, model)


def test_bag_without_columns_and_not_a_bag(tmp_path, capsys):
    path = _imu_and_motor().write(tmp_path)
    with pytest.raises(AttendInputError, match=r"flight: a ROS bag; reading it needs the model file's \[log.columns\]"):
        io.read_log(path)
    (tmp_path / "junk.mcap").write_bytes(b"not a bag at all")
    (tmp_path / "model.toml").write_text(_model(IMU_COLUMNS, outputs=("gyro_x", "gyro_y"), inputs="motor"))
    with pytest.raises(AttendInputError, match=r"junk.mcap: not a readable ROS bag"):
        io.read_log(tmp_path / "junk.mcap", io.read_model(tmp_path / "model.toml"))
    (tmp_path / "folder").mkdir()
    with pytest.raises(AttendInputError, match=r"folder is a directory; expected a CSV file, or a ROS 2 bag folder"):
        io.read_log(tmp_path / "folder")
    assert main(["estimate", str(tmp_path / "model.toml"), str(tmp_path / "junk.mcap")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "junk.mcap: not a readable ROS bag" in err


@pytest.mark.parametrize("log, columns, expected", [
    ("rate_hz = 100\ndt = 0.01", IMU_COLUMNS, "[log]: give rate_hz or dt (the grid's rate or step), not both"),
    ("rate_hz = 0", IMU_COLUMNS, "[log] rate_hz: expected a number > 0 (Hz), got 0"),
    ('resample = "cubic"', IMU_COLUMNS, "[log] resample: expected 'linear' or 'hold', got 'cubic'"),
    ('stamps = "bag"', IMU_COLUMNS, "[log] stamps: expected 'auto' or 'header' or 'receive', got 'bag'"),
    ('grid_topic = "/gps"', IMU_COLUMNS, "[log] grid_topic: '/gps' is not a topic of [log.columns]; expected one of "
                                         "'/imu', '/motor'"),
    ("max_gap = -1", IMU_COLUMNS, "[log] max_gap: expected a number > 0 (seconds), got -1"),
    ("", IMU_COLUMNS.replace("gyro_y", "gyro_z"), "[log.columns] has no entry for the column 'gyro_y' ([outputs] columns)"),
    ("", IMU_COLUMNS.replace("motor = ", "motors = "), "[log.columns] has no entry for the column 'motor' "
                                                       "([[inputs]] 'u' column)"),
    ("", IMU_COLUMNS + '\nt = { topic = "/imu", field = "header.stamp.sec" }', "[log.columns] t: the name of the log's "
                                                                               "time column"),
    ("", IMU_COLUMNS.replace('field = "data"', 'field = "data..x"'), "[log.columns] motor field: expected a path of "
                                                                      "field names separated by dots"),
    ("", IMU_COLUMNS.replace('field = "data"', 'fields = "data"'), "[log.columns] motor: unknown key 'fields'"),
    ("", IMU_COLUMNS.replace('topic = "/motor", ', ""), "[log.columns] motor: needs topic"),
])
def test_model_file_keys_checked(tmp_path, log, columns, expected):
    (tmp_path / "model.toml").write_text(_model(columns, log, outputs=("gyro_x", "gyro_y"), inputs="motor"))
    with pytest.raises(AttendInputError) as error:
        io.read_model(tmp_path / "model.toml")
    assert str(error.value).startswith(str(tmp_path / "model.toml")) and expected in str(error.value)


def test_bag_keys_without_columns_and_conflicting_dt(tmp_path):
    text = _model(IMU_COLUMNS, "rate_hz = 100", outputs=("gyro_x", "gyro_y"), inputs="motor")
    (tmp_path / "model.toml").write_text(text[:text.index("[log.columns]")])
    with pytest.raises(AttendInputError, match=r"\[log\] rate_hz: settings for reading a ROS bag; add a \[log.columns\]"):
        io.read_model(tmp_path / "model.toml")
    (tmp_path / "model.toml").write_text(text.replace("[model]\n", "[model]\ndt = 0.02\n"))
    with pytest.raises(AttendInputError, match=r"\[log\] rate_hz = 100 \(dt 0.01 s\) but \[model\] dt = 0.02 s"):
        io.read_model(tmp_path / "model.toml")
