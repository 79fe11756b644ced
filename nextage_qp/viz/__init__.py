"""Pictures: figures of the control loop, of a manipulation run and of a sweep; markers, video and the viewer.

Everything here imports matplotlib or the renderer lazily from the functions that need them, so the library
and the sweep workers stay free of rendering.
"""
