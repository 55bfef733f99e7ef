"""uav-energy: onboard energy and endurance estimation for multirotor UAVs."""

__version__ = "0.1.0"
