"""controllers.balance."""
