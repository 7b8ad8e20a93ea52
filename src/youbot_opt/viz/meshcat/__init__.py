"""meshcat."""
