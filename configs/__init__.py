"""Packaged scenario configs (YAML); see ilc_steering.config."""
