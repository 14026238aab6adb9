"""sensact: learn a robot's action and sensor models from its own logs (Stronger 2008)."""

__version__ = "0.1.0"
