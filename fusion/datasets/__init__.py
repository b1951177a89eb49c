"""Readers of recorded data sets used to test the library against reality."""
