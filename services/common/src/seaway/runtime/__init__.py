"""The runtime every service loop stands on: the bus, clocks, the run description and the service
scaffold (arguments, logging, signals, health).
"""
