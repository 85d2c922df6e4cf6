"""MJCF files below the recorder and the contact designer: their files, loading, `<pair>`s."""
