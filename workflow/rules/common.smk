def study_targets():
    return []
