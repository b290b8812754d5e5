# rules: features (to be written)
