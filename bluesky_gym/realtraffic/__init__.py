"""Recorded air traffic: cleaned ADS-B flights, scenarios built from them, and their fidelity."""
