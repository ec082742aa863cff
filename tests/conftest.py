"""Suite-wide collection order: the tests marked ``heavy`` (several seconds each, mostly both
engines running the rover) go first. ``pytest -n 2`` hands tests out in collection order, so a
long test met at the end keeps one worker busy while the other idles; longest first is the usual
remedy for that (list scheduling). The order within each group is the collection order."""


def pytest_collection_modifyitems(items):
    items.sort(key=lambda item: item.get_closest_marker("heavy") is None)
