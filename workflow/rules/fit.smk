# rules: fit (to be written)
