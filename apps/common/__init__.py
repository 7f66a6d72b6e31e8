"""What every app shares: the command-line conventions and the experiment runner."""
