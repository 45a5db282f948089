"""Phase 1: K-means symbols of the observations (distance metrics, cluster-count policies)."""
