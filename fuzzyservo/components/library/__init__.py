"""Component types a rig file composes: one module each, each defining ``COMPONENTS``.

Found by :func:`fuzzyservo.components._declare.registry`; nothing lists them by hand.
"""
