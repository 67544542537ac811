"""Command-line interface (click)."""
import click


@click.group()
def main() -> None:
    """distctrl: CNC distance control."""
