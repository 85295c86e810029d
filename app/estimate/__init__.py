"""The motion filter: the shared model, the readable reference on filterpy, the compiled twin the
pipeline runs, and the offline smoother.
"""
