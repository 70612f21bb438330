"""Component types a rig file composes: one module each, each defining ``COMPONENTS``.

Found by :func:`fuzzyservo.components.declare.registry`; nothing lists them by hand.
"""
