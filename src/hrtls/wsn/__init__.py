"""Sensor-network self-localization with mobile agents (Inderst thesis Ch. 3.5, 5, 6.4)."""
