"""Files and figures: EXR/PNG writing (atomic), OpenEXR standard attributes, image metrics."""
