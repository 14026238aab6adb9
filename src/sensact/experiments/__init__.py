"""The thesis's experiments and ours as code, for ``sensact reproduce``; nothing else imports them.

* ``track1d`` and ``turtlebot``: chapter 3 (sec. 3.3), simulated and real;
* ``field2d``, ``em1d``, ``diffdrive``, ``real``, ``turtlebot_em`` and ``shared_data``: chapter 4, simulated
  and on MRCLAM and the Turtlebot;
* ``velodyne_car``: chapter 5 (sec. 5.4);
* ``monitor`` and ``coverage``: whether `sensact monitor` and `--uncertainty` say the truth.
"""
