"""What the crossings and steady samples add up to: the combined crossings, the left/right and up/down
pairing, and the regression over every steady sample.
"""
