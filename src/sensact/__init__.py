"""sensact: learn a robot's action and sensor models from its own logs (Stronger 2008).

The layers, each importing only those below it (``tests/test_layering.py``): ``errors``, ``limits``,
``reprs``, ``outputs``, ``records`` and ``progress`` (plain values); ``health``, ``config``, ``engine`` and
``core/``; ``models/`` and ``logs/``; ``learn/``, ``sim/`` and ``io/``; ``evaluate/`` and ``presets/``;
``report/``; ``app/``; ``experiments/``; ``cli/`` (and ``__main__``, ``python -m sensact``).
"""

__version__ = "0.1.0"
