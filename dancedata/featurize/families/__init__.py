"""The feature families featurize runs: ``motion*.py`` and ``audio*.py``, each registered with
``@register_family``.
"""
