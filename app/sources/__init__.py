"""Where frames come from: log files, session folders and live buses, their health, playback, and the
bulk readers that skip the frames nobody decodes.
"""
