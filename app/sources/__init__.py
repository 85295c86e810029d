"""Where frames come from: log files and live buses, their health, playback, and the bulk readers that
skip the frames nobody decodes.
"""
