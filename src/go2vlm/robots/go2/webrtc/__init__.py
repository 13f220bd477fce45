"""The Go2's WebRTC route (the Unitree app's): signalling and data-channel codec (`codec.py`, pure),
the asyncio link (`link.py`, aiortc) and the go2 driver's transport over it (`transport.py`).
Needs the `webrtc` extra: `pip install go2vlm[webrtc]`."""
