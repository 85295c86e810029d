"""Where and how c2n writes: ``paths`` checks every output before any work (never an input,
never a user's file, standard output once), ``files`` writes each aside and swaps it in whole.
Every command may use both; they import nothing of the stages."""
