"""What a run is made of: the kinds of component, the plugin hooks, the registry that collects
the components (built-ins and plugins), their typed configs and the checks of a config."""
