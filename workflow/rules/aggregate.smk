# rules: aggregate (to be written)
