"""topomap's Hydra configs: ``config.yaml``, experiment presets and launcher examples.

The component options (``env=office``, ``clusters=bic``, ...) are not files: each is the typed
config derived from its component's signature, stored by :func:`topomap.app.compose.store.store_configs`.
"""
