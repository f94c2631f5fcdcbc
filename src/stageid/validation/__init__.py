"""stageid.validation"""
