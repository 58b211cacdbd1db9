"""Labelled datasets of simulated acceleration windows."""
