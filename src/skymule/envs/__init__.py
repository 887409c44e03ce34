"""Learning environments over the skymule engine (optional extras)."""
