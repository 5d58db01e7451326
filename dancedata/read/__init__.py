"""Reading a store: the reader, its views, windows, batching and torch datasets."""
