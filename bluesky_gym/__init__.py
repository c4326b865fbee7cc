"""BlueSky-Gym."""
