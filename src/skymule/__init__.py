"""skymule: UAV data-mule missions, simulated, replayed, bounded and reported."""

__version__ = "0.1.0"
