"""Binary formats that travel between processes: the studio's sockets, NATS and take files share them."""
