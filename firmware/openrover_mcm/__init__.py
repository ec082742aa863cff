"""The OpenRover motor-controller module (one per wheel): an Arduino Pro Mini sketch."""
