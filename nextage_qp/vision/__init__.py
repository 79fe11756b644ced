"""Robot cameras: rendering, depth noise, object poses from depth frames, the perception block."""
