"""stageid.closedloop"""
