"""The click command-line front end: thin commands over akdctl.drive operations."""
