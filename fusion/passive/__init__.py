"""Passive narrowband processing: acquisition, bearing tracking, track quality, crossings."""
