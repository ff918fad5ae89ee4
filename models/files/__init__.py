"""What the package writes: the one encoder per output format for every name a user gives, and the one
atomic writer that never follows a link and never leaves a file half-written. Anything that turns a user's
string into bytes on disk belongs here."""
