"""
The node's ``/diagnostics``: the driver's report as a diagnostic_msgs/DiagnosticArray.

The driver keeps the counters and decides the level and message
(:mod:`gyro_emulator.emulation.driver.book`). :class:`DiagnosticsThread`
calls the node once per ``diagnostics_period_s`` on the steady clock, so the
status goes out also while a simulation is paused; :func:`to_msg` builds the
message of one report.
"""

import threading
import time

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from gyro_emulator.emulation.driver.book import ERROR, OK, WARN

_LEVEL_BYTES = {OK: DiagnosticStatus.OK, WARN: DiagnosticStatus.WARN,
                ERROR: DiagnosticStatus.ERROR}


def _text(value):
    if value is None:
        return ''
    if isinstance(value, bool):
        return 'true' if value else 'false'
    if isinstance(value, float):
        return f'{value:.6g}'
    return str(value)


def to_msg(report, stamp, name, hardware_id):
    """
    Build the DiagnosticArray of one report.

    Parameters
    ----------
    report : gyro_emulator.emulation.driver.book.Report
        The status to publish.
    stamp : builtin_interfaces.msg.Time
        header.stamp (node clock).
    name, hardware_id : str
        DiagnosticStatus name and hardware_id.

    """
    msg = DiagnosticArray()
    msg.header.stamp = stamp
    status = DiagnosticStatus(level=_LEVEL_BYTES[report.level], name=name,
                              message=report.message, hardware_id=hardware_id)
    status.values = [KeyValue(key=k, value=_text(v)) for k, v in report.values]
    msg.status = [status]
    return msg


class DiagnosticsThread:
    """
    Call ``diagnose(elapsed_s)`` every ``period_s`` of the steady clock until stopped.

    Parameters
    ----------
    node : rclpy.node.Node
        The node: the thread ends once its context is down, and an error is
        logged (then the thread ends) only while the context is up.
    period_s : float
        Period, s (steady clock).
    diagnose : callable
        ``diagnose(elapsed_s)``: publish one status; ``elapsed_s`` is the
        steady time since the previous call (or the start), s.

    """

    def __init__(self, node, period_s, diagnose):
        self._node = node
        self._period_s = period_s
        self._diagnose = diagnose
        self._last = time.monotonic()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._loop, daemon=True,
                                        name='gyro_emulator_diagnostics')
        self._thread.start()

    def _loop(self):
        context = self._node.context
        while not self._stop.wait(self._period_s):
            if not context.ok():
                return
            now = time.monotonic()
            elapsed, self._last = now - self._last, now
            try:
                self._diagnose(elapsed)
            except Exception as exc:  # noqa: B902 - a shutdown race must not kill the log
                if context.ok():
                    self._node.get_logger().error(f'diagnostics failed: {exc!r}')
                return

    def stop(self):
        """Stop the thread (waits up to 5 s for it)."""
        self._stop.set()
        self._thread.join(5.0)
