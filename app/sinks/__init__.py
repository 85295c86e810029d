"""Where results go: the dashboard, the event printer, progress, the recorder, events.csv, the summary,
the channel trace and its files, plots, the HTML kit and the report.
"""
