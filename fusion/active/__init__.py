"""Multistatic active sonar: fuzzy association, clutter map and tracker."""
