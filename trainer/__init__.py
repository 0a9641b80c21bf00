"""fogsf: FOG thermal scale-factor error from chamber data to firmware."""

__version__ = "0.1.0"
