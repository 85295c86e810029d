"""The sim-to-real gap: where a measured drive departs from the nominal bicycle model, which
unmodelled effect explains it, and how far the gap shrinks once that effect is added."""
