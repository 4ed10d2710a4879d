"""The experiment runner: samples a rig, applies inputs, feeds identifiers."""
