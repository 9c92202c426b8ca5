"""The machine a bench ran on: CPU model, cores, Python and library versions."""

import datetime
import os
import platform
from typing import TypedDict


class MachineInfo(TypedDict):
    """The machine a bench ran on, for its page and JSON."""

    date: str
    cpu: str
    cores: int | None
    usable_cores: int | None
    os: str
    python: str
    numpy: str
    mpmath: str


def cpu_model() -> str:
    try:
        with open('/proc/cpuinfo', encoding='utf-8') as f:
            for line in f:
                if line.startswith('model name'):
                    return line.split(':', 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def machine_info() -> MachineInfo:
    import mpmath
    import numpy
    usable: int | None
    try:
        usable = len(os.sched_getaffinity(0))
    except AttributeError:
        usable = os.cpu_count()
    return {
        'date': datetime.datetime.now(datetime.timezone.utc).strftime('%Y-%m-%d %H:%M UTC'),
        'cpu': cpu_model(),
        'cores': os.cpu_count(),
        'usable_cores': usable,
        'os': platform.platform(terse=True),
        'python': platform.python_version(),
        'numpy': numpy.__version__,
        'mpmath': mpmath.__version__,
    }


def machine_line(info: MachineInfo) -> str:
    return (f"{info['date']} · {info['cpu']}, {info['cores']} cores "
            f"({info['usable_cores']} usable) · {info['os']} · Python {info['python']} · "
            f"numpy {info['numpy']} · mpmath {info['mpmath']}")
