"""The app's own components, registered like any plugin's: where a run's data comes from
(``data=simulate|file|rosbag``) and where a finished run is also recorded (``logger=mlflow``)."""
