"""The gravitational search algorithm, its search spaces, test functions and executors."""
