"""Micrographs of real films: read them, find their dots, and measure them as a simulated board is measured."""
