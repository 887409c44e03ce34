"""Simulation core: the slot contract, the engines that apply it and the mission log."""
