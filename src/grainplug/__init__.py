"""grainplug."""
