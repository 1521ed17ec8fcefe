"""Errors, array checks, atomic files and progress: what every other part of core/ stands on."""
