"""What the flight costs: rotor power in hover and forward flight, and the LiPo pack it
draws from."""
