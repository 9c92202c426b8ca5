"""`planter demo`: the whole machine on a simulated CAN bus, judged.

* `options`: what a run is asked to do (`DemoOptions`), the bag path checked first;
* `field`: the field run (speed profile with turns, a stop, sensor glitches);
* `run`: the process layout and life cycle (`prepare(options).run()`): the design node, the
  monitor and the field sensors in this process, the sync node with the simulated drives in
  a process of its own (`sync_process`), all in a private DDS domain;
* `report`: the figures per row and of the command path, for people;
* `verdict`: PASS or FAIL with every reason, and the exit code;
* `samples`: regenerates the committed sample bags from the real monitor node.

The command line (`planter_ros.cli.demo`) only parses options into a `DemoOptions`.
"""

from .options import DemoOptions

__all__ = ['DemoOptions']
