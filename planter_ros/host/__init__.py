"""The computer the product runs on, one place for its plumbing (standard library only):
helper processes that die with their parent, also on SIGKILL (`processes`); SIGINT and SIGTERM
as a stop (`stop_signals`); a private DDS domain on the host's loopback (`dds_domain`); the
real-time set-up of a process: SCHED_FIFO, locked memory, CPU share (`realtime`)."""

__all__ = ['dds_domain', 'processes', 'realtime', 'stop_signals']
