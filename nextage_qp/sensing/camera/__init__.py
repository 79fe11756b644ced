"""Robot cameras: rendering, depth noise and stereo, object poses fitted to depth frames."""
