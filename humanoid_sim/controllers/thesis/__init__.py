"""controllers.thesis."""
