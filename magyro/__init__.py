"""magyro: gyroscope calibration via the magnetometer (Wu & Pei), one CasADi/IPOPT least squares."""
__version__ = "0.1.0"
