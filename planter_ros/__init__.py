"""planter_ros: design and drive the planting unit of a seedling transplanter."""
