def feature_targets():
    return []
