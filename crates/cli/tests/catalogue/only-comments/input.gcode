; nothing
(also nothing)

