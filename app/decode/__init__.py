"""Frames into role values: the decoder, the sensor status, the frame counts and the signal readers."""
