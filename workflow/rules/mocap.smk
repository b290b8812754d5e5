# rules: mocap (to be written)
