"""`go2vlm view`: live data in Foxglove over a WebSocket (foxglove-sdk)."""
