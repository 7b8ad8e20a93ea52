"""trajopt."""
