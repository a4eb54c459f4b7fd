"""Spinning that survives the asynchronous shutdown of SIGINT/SIGTERM, and closing down."""

import rclpy


def spin_once(executor, timeout_sec):
    """
    Spin ``executor`` once; return False once its context has shut down.

    rclpy's SIGINT/SIGTERM handler shuts the context down asynchronously, so
    the wait set of the next spin, or a publish inside a callback, can raise
    ``RCLError`` ("the given context is not valid"). An error raised after
    the shutdown is the shutdown itself and ends the loop; an error while the
    context is still valid is re-raised.

    Parameters
    ----------
    executor : rclpy.executors.Executor
        The executor to spin.
    timeout_sec : float
        Longest wait for work, s (also how often the context is re-checked,
        since the signal handler's wake-up can be missed).

    """
    context = executor.context
    if not context.ok():
        return False
    try:
        executor.spin_once(timeout_sec=timeout_sec)
    except Exception:  # noqa: B902 - any error after shutdown is the shutdown
        if context.ok():
            raise
        return False
    return context.ok()


def close(node):
    """Destroy ``node`` (if any) and shut rclpy down, however the run ended."""
    if node is not None:
        node.destroy_node()
    rclpy.try_shutdown()
