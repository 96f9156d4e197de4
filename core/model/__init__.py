"""The geozone model: the pipeline over bench pairs, prediction, surfaces, evaluation and the build."""
