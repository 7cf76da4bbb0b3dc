"""The host's side of the bench bridge (docs/design.md §8): the link's message table and codec, and the
real-time session that streams samples to a bridge and reads back what the board did."""
