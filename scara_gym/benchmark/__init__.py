"""The seed paper's tasks a-c, the scipy reference, and the ``scara-c11`` command
(``reproduce``, ``bench``).
"""
